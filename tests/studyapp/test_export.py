"""Export and analysis of a small ranking study built straight through the ORM."""

from datetime import timedelta

import pandas as pd
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError
from django.utils import timezone

from studyapp.results.export import responses_frame
from studyapp.survey.models import Participant, Stimulus, Study, Trial, TrialItem

SOURCES = ("real", "a2m", "cond_gru")
# participant -> trials of (action, ranks by position, or None when not answered yet)
SESSIONS = {
    "p1": [("eat", (1, 2, 3)), ("walk", (3, 1, 2))],
    "p2": [("walk", (2, 1, 3)), ("eat", (1, 3, 2))],
    "p3": [("eat", (2, 3, 1)), ("walk", None)],
}


def build_study(slug="rank-test"):
    """Create a ranking study with three participants; p1 completed it, p3 did not answer all."""
    study = Study.objects.create(slug=slug, title="Ranking test", clips_per_trial=3)
    stimuli = {
        (action, source): Stimulus.objects.create(
            study=study, action=action, source=source, video=f"clips/{action}-{source}.mp4",
            duration=2.0, motion_hash=f"m-{action}-{source}", video_hash=f"v-{action}-{source}",
        )
        for action in ("eat", "walk")
        for source in SOURCES
    }
    start = timezone.now()
    for seed, (name, trials) in enumerate(SESSIONS.items()):
        participant = Participant.objects.create(
            study=study, seed=seed, external_ids={"prolific_pid": f"PID-{name}"},
            completed_at=start if name == "p1" else None,
        )
        for index, (action, ranks) in enumerate(trials):
            trial = Trial.objects.create(
                participant=participant, index=index, action=action, shown_at=start,
                answered_at=start + timedelta(seconds=9) if ranks else None,
                time_ms=9000 if ranks else None,
            )
            # Sources appear on screen in a participant-specific order.
            order = SOURCES[seed % 3 :] + SOURCES[: seed % 3]
            for position, source in enumerate(order):
                TrialItem.objects.create(
                    trial=trial, stimulus=stimuli[action, source], position=position,
                    answers={"preference": ranks[position]} if ranks else {}, plays=1,
                )
    return study


def stored_ranks(study):
    """Return the ranked items of ``study`` as a frame read straight from the ORM."""
    items = TrialItem.objects.filter(trial__participant__study=study).exclude(answers={})
    return pd.DataFrame(
        [(p, t, pos, source, answers["preference"]) for p, t, pos, source, answers in
         items.values_list("trial__participant_id", "trial__index", "position",
                           "stimulus__source", "answers")],
        columns=["participant", "trial", "position", "source", "rank"],
    )


@pytest.mark.django_db
def test_export_writes_one_row_per_judgement(tmp_path):
    study = build_study()
    out = tmp_path / "responses.csv"
    call_command("export_responses", study=study.slug, out=str(out), stdout=None)
    table = pd.read_csv(out)
    expected = stored_ranks(study).sort_values(
        ["participant", "trial", "position"], ignore_index=True
    )
    assert len(table) == 15  # 5 answered trials x 3 clips; p3's second trial has no ranks
    pd.testing.assert_frame_equal(table[expected.columns], expected, check_dtype=False)
    assert table.columns[:4].tolist() == ["study", "study_type", "participant", "prolific_pid"]
    assert table["n_items"].eq(3).all()
    assert table.groupby("participant")["completed"].first().tolist() == [True, False, False]
    assert table["prolific_pid"].unique().tolist() == ["PID-p1", "PID-p2", "PID-p3"]
    assert table["answered_at"].str.match(r"\d{4}-\d\d-\d\dT").all()
    assert set(table["stimulus_token"]) <= set(Stimulus.objects.values_list("token", flat=True))


@pytest.mark.django_db
def test_analyze_counts_exactly_the_stored_ranks(tmp_path, capsys):
    study = build_study()
    call_command("analyze", study=study.slug, out=str(tmp_path))
    shares = pd.read_csv(tmp_path / "rank_shares.csv", index_col="source")
    counts = pd.crosstab(stored_ranks(study)["source"], stored_ranks(study)["rank"])
    for source, row in counts.iterrows():
        for rank, count in row.items():
            share = shares.loc[source, f"rank_{rank}"]
            assert round(share * shares.loc[source, "n_judgements"]) == count
    assert shares["n_judgements"].sum() == 15
    assert len(pd.read_csv(tmp_path / "responses.csv")) == 15
    by_action = pd.read_csv(tmp_path / "rank_shares_by_action.csv")
    assert by_action.groupby("action")["n_judgements"].sum().to_dict() == {"eat": 9, "walk": 6}
    assert (tmp_path / "rank_shares.png").read_bytes().startswith(b"\x89PNG")
    summary = capsys.readouterr().out
    assert "3 participants, 15 judgements" in summary
    # Summary lines look like "  1. a2m: mean rank 1.40, ...".
    listed = [
        line.split(". ", 1)[1].split(":")[0] for line in summary.splitlines() if line[:2] == "  "
    ]
    assert listed == shares.sort_values("mean_rank").index.tolist()


@pytest.mark.django_db
def test_completed_only_keeps_finished_participants(tmp_path):
    study = build_study()
    call_command("analyze", study=study.slug, out=str(tmp_path), completed_only=True)
    assert pd.read_csv(tmp_path / "rank_shares.csv")["n_participants"].max() == 1


@pytest.mark.django_db
def test_unknown_study_lists_the_slugs(tmp_path):
    build_study("alpha")
    Study.objects.create(slug="beta", title="Beta")
    with pytest.raises(CommandError, match="known studies: alpha, beta"):
        call_command("export_responses", study="gamma", out=str(tmp_path / "x.csv"))
    with pytest.raises(CommandError, match="Unknown study 'gamma'"):
        call_command("analyze", study="gamma", out=str(tmp_path))


@pytest.mark.django_db
def test_study_without_answers_exports_header_and_refuses_analysis(tmp_path, capsys):
    study = Study.objects.create(slug="empty", title="Empty")
    out = tmp_path / "empty.csv"
    call_command("export_responses", study="empty", out=str(out))
    assert "no answers yet" in capsys.readouterr().out
    header = out.read_text().splitlines()
    assert len(header) == 1 and header[0].startswith("study,study_type,participant,")
    assert responses_frame(study).empty
    with pytest.raises(CommandError, match="no answers"):
        call_command("analyze", study="empty", out=str(tmp_path / "analysis"))


@pytest.mark.django_db
def test_export_to_parquet(tmp_path):
    pytest.importorskip("pyarrow")
    study = build_study()
    out = tmp_path / "responses.parquet"
    call_command("export_responses", study=study.slug, out=str(out))
    table = pd.read_parquet(out)
    assert len(table) == 15
    assert str(table["rank"].dtype) == "Int64"


@pytest.mark.django_db(transaction=True)
def test_admin_results_page_runs_the_analysis_in_the_background(admin_client, settings, tmp_path):
    import time

    settings.VAR_DIR = tmp_path
    study = build_study("rank-results")
    page = f"/admin/survey/study/{study.pk}/results/"
    assert "No analysis yet" in admin_client.get(page).content.decode()
    assert admin_client.post(page).status_code == 302
    report = tmp_path / "reports" / study.slug / "report.html"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if report.is_file() and "</html>" in report.read_text(errors="replace").lower():
            break
        time.sleep(0.2)
    assert report.is_file(), "the background analysis wrote no report"
    assert "Analysis of" in admin_client.get(page).content.decode()
    shown = admin_client.get(f"{page}report/")
    assert shown.status_code == 200 and b"<html" in b"".join(shown.streaming_content).lower()
    assert admin_client.get("/admin/survey/study/").content.decode().count("/results/") >= 1


@pytest.mark.django_db
def test_bots_are_exported_and_reported_as_simulated(tmp_path):
    from studyapp.participation.bots import USER_AGENT
    from studyapp.results.export import participants_frame

    study = build_study("rank-bots")
    Participant.objects.filter(study=study, seed=1).update(
        user_agent=USER_AGENT, demographics={"age_range": "18-24", "gender": "female"})
    table = responses_frame(study)
    assert table.groupby("participant")["simulated"].first().tolist() == [False, True, False]
    assert participants_frame(study)["simulated"].tolist() == [False, True, False]
    call_command("analyze", study=study.slug, out=str(tmp_path), bootstrap=20, no_audit=True)
    page = (tmp_path / "report.html").read_text()
    assert "1 of the 3 analysed participants was a bot" in page
    assert "18-24" not in page.split("<h2>Methods</h2>", 1)[1].split("</p>", 1)[0]

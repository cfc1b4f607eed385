"""An arena: a standing adaptive study of text-to-motion models that new models join later
(`arena add` of an MDM results.npy: imported, prompt coverage checked, rendered in the
arena's framing and byte budgets, audited for blindness, registered, aimed at), that
retires models without losing their history (`arena retire`), and its public leaderboard
(`/arena/<slug>/` and its JSON)."""

import json
from io import StringIO
from pathlib import Path

import pytest
import yaml
from django.core.exceptions import ValidationError
from django.core.files.storage import default_storage
from django.core.management import CommandError, call_command

from studyapp.participation import adaptive
from studyapp.participation import arena as arena_settings
from studyapp.participation.assignment import stimuli_by_action
from studyapp.stimuli.config import ConfigError, load_config
from studyapp.survey.models import Stimulus, Study
from studyapp.survey.study_types import list_study_types
from tests.motion import untrusted_files
from tests.studyapp.mdm_results import write_mdm_results

pytestmark = [pytest.mark.slow, pytest.mark.django_db(transaction=True)]

ROOT = Path(__file__).resolve().parents[2]
PROMPTS = ["a person jumps twice", "someone waves with the right hand", "a man sits down"]
SLUG = "arena"


@pytest.fixture(scope="module")
def render_cache(tmp_path_factory):
    """One cache of motions and renders for the module (keyed by content)."""
    return tmp_path_factory.mktemp("arena-cache")


def build_arena(tmp_path, cache, **arena):
    for i, name in enumerate(("model_a", "model_b")):
        write_mdm_results(tmp_path / name / "results.npy", PROMPTS, repetitions=1, seed=i + 1)
    overrides = [
        f"sources.0.file={tmp_path / 'model_a' / 'results.npy'}",
        f"sources.1.file={tmp_path / 'model_b' / 'results.npy'}",
        "prompts_from=null", f"prompts={json.dumps(PROMPTS)}", "frames=20", "render.size=64",
        f"slug={SLUG}", "study.repeat_trials=0", "study.ask_demographics=false",
        "study.design=adaptive", "study.trials_per_participant=3",
        f"study.arena={json.dumps({'min_votes': 4, 'baseline': 'model_a', **arena})}",
    ]
    args = ["build_stimuli", str(ROOT / "studies" / "mdm_pairwise.yaml"), "--out",
            str(tmp_path / "build"), "--cache", str(cache)]
    for override in overrides:
        args += ["--set", override]
    call_command(*args, stdout=StringIO())
    return Study.objects.get(slug=SLUG)


@pytest.fixture
def arena(tmp_path, media_root, render_cache):
    return build_arena(tmp_path, render_cache)


def add(tmp_path, render_cache, name, **options):
    out = StringIO()
    call_command("arena", "add", "--study", SLUG, "--file", str(tmp_path / name / "results.npy"),
                 "--name", name, "--out", str(tmp_path / "build"), "--cache", str(render_cache),
                 *sum(([f"--{k}", str(v)] for k, v in options.items()), []), stdout=out)
    return out.getvalue()


def test_settings_are_checked_in_the_config_and_on_the_study():
    base = ROOT / "studies" / "mdm_pairwise.yaml"
    with pytest.raises(ConfigError, match="set design: adaptive"):
        load_config(base, ["study.arena={}"])
    with pytest.raises(ConfigError, match="arena.min_vote: not a setting"):
        load_config(base, ["study.design=adaptive", "study.arena={min_vote: 3}"])
    config = load_config(base, ["study.design=adaptive", "study.arena={}"])
    assert config.study_options["arena"] == arena_settings.DEFAULTS
    # The admin and every save check them too.
    paired = next(name for name in list_study_types() if adaptive.model(name) == "pairs")
    with pytest.raises(ValidationError, match="set design: adaptive"):
        Study.objects.create_study(paired, "not-adaptive", "X", arena={"min_votes": 3})
    # An arena stands: a stopping rule would close it for every source added later.
    with pytest.raises(ConfigError, match="no stopping rule"):
        load_config(base, ["study.design=adaptive", "study.arena={}",
                           "study.stop_when={judgements: 100}"])
    with pytest.raises(ValidationError, match="no stopping rule"):
        Study.objects.create_study(paired, "stopping", "X", design="adaptive",
                                   arena={"min_votes": 3},
                                   stop_when={"judgements": 100})
    # Sets of sources (best of k, ranking) and types without a worth model are refused.
    for other in [name for name in list_study_types() if adaptive.model(name) != "pairs"]:
        with pytest.raises(ValidationError, match="worth model"):
            Study.objects.create_study(other, f"no-worth-{other}".replace("_", "-"), "X",
                                       design="adaptive", arena={"min_votes": 3})


def test_a_source_added_from_results_npy_is_rendered_blind_registered_and_aimed_at(
        arena, tmp_path, render_cache, make_bot):
    before = {s.pk for s in arena.stimuli.all()}
    # The new model wrote the prompts in its own order and spelling, twice each.
    other = [p.capitalize() + "." for p in PROMPTS][::-1]
    write_mdm_results(tmp_path / "model_c" / "results.npy", other, repetitions=2, seed=7)
    said = add(tmp_path, render_cache, "model_c")  # the deep audit, as by default
    assert "added model_c (3 clips of 3 prompts" in said and "audit passed" in said
    arena.refresh_from_db()
    new = arena.stimuli.exclude(pk__in=before)
    judged = new.filter(role=Stimulus.Role.JUDGED)
    assert sorted(judged.values_list("prompt", flat=True)) == sorted(PROMPTS)
    assert set(judged.values_list("source", flat=True)) == {"model_c"}
    assert new.filter(role=Stimulus.Role.CATCH).count() == 2 * len(PROMPTS)
    # The same byte size, length and naming as every clip of the arena.
    stimuli = list(arena.stimuli.all())
    assert len({default_storage.size(s.video) for s in stimuli}) == 1
    assert len({s.duration for s in stimuli}) == 1
    assert not any("model" in s.video for s in stimuli)
    # Registered: shown to new participants, in the kept config, and the adaptive design's
    # distribution now spans it (no comparisons yet: its pairs weigh most).
    assert "model_c" in {source for row in stimuli_by_action(arena).values() for source in row}
    assert arena.sampling["sources"] == ["model_a", "model_b", "model_c"]
    kept = yaml.safe_load((tmp_path / "build" / "config.yaml").read_text())
    assert [s["name"] for s in kept["sources"]] == ["model_a", "model_b", "model_c"]
    assert kept["prompts"] == PROMPTS and kept["frames"] == 20
    assert "model_c" in arena.arena_state["added"]
    # Participants' pages name no source, the new one's included.
    bot = make_bot(arena)
    pages = [bot.join().content]
    while (trial := bot.participant().current_trial()) is not None:
        pages.append(bot.trial_page().content)
        pages.append(bot.answer(bot.answer_data(trial), follow=True).content)
    assert len(pages) > 3 and not any(b"model_" in page or b"/arena/" in page for page in pages)
    # The same name twice is refused; a later source is drawn in the framing kept.
    with pytest.raises(CommandError, match="has a source 'model_c' already"):
        add(tmp_path, render_cache, "model_c", audit="none")
    assert arena.arena_state["framing"]["dims"] == 3
    write_mdm_results(tmp_path / "model_d" / "results.npy", PROMPTS, repetitions=1, seed=8)
    add(tmp_path, render_cache, "model_d", audit="none")
    arena.refresh_from_db()
    assert arena.sampling["sources"] == ["model_a", "model_b", "model_c", "model_d"]
    assert len({default_storage.size(s.video) for s in arena.stimuli.all()}) == 1


def test_a_file_missing_prompts_is_refused_naming_them_and_the_fix(arena, tmp_path,
                                                                   render_cache):
    write_mdm_results(tmp_path / "partial" / "results.npy", PROMPTS[:1], repetitions=1, seed=9)
    with pytest.raises(CommandError) as error:
        add(tmp_path, render_cache, "partial", audit="none")
    message = str(error.value)
    assert "no motion for 2 of the arena's 3 prompts" in message
    assert repr(PROMPTS[1]) in message and repr(PROMPTS[2]) in message
    assert f"arena prompts --study {SLUG}" in message
    assert not arena.stimuli.filter(source="partial").exists()
    out = StringIO()
    call_command("arena", "prompts", "--study", SLUG, stdout=out)
    assert out.getvalue().splitlines() == PROMPTS
    # A tampered results.npy is data: refused, naming the file, and nothing in it runs.
    marker = tmp_path / "ran"
    untrusted_files.mdm_results(tmp_path / "tampered" / "results.npy", marker)
    with pytest.raises(CommandError, match="results.npy"):
        add(tmp_path, render_cache, "tampered", audit="none")
    assert not marker.exists() and not arena.stimuli.filter(source="tampered").exists()


def test_a_retired_source_is_never_shown_again_and_keeps_its_history(
        arena, tmp_path, render_cache, live_server, client, monkeypatch):
    from studyapp.results import leaderboard

    take_part(live_server, seed=1)
    write_mdm_results(tmp_path / "model_c" / "results.npy", PROMPTS, repetitions=1, seed=7)
    add(tmp_path, render_cache, "model_c", audit="none")
    # The design aims at the new source: no comparisons of it yet, the widest posterior.
    arena.refresh_from_db()
    sampling = arena.sampling
    new = sampling["sources"].index("model_c")
    with_new = sum(p for pair, p in zip(sampling["pairs"], sampling["p"]) if new in pair)
    assert sampling["comparisons"] > 0 and with_new > 2 / 3
    call_command("arena", "board", "--study", SLUG, "--bootstrap", "0", stdout=StringIO())
    started = []
    monkeypatch.setattr(leaderboard, "run_job", lambda kind, **params: started.append(params))
    client.get(f"/arena/{SLUG}.json")
    assert not started  # fresh
    call_command("arena", "retire", "--study", SLUG, "--name", "model_b", stdout=StringIO())
    arena.refresh_from_db()
    assert arena_settings.retired(arena) == ["model_b"]
    assert arena.sampling["sources"] == ["model_a", "model_c"]
    assert all("model_b" not in row for row in stimuli_by_action(arena).values())
    client.get(f"/arena/{SLUG}.json")
    assert len(started) == 1  # the board is older than the retirement: computed again
    call_command("simulate_participants", study=SLUG, n=2, url=live_server.url, pace=0,
                 seed=3, stdout=StringIO())
    shown = Stimulus.objects.filter(study=arena, items__trial__participant__seed__isnull=False,
                                    items__trial__kind="main").values_list("source", flat=True)
    later = arena.participants.order_by("-pk")[:2]
    assert not Stimulus.objects.filter(items__trial__participant__in=later,
                                       items__trial__kind="main", source="model_b").exists()
    assert "model_b" in set(shown)  # answered before it was retired
    with pytest.raises(CommandError, match="would leave arena"):
        call_command("arena", "retire", "--study", SLUG, "--name", "model_a")
    call_command("arena", "board", "--study", SLUG, "--bootstrap", "50", stdout=StringIO())
    board = {row["source"]: row for row in
             live_json(live_server.url)["sources"]}
    assert board["model_b"]["retired"] and board["model_b"]["votes"] > 0
    assert board["model_a"]["anchor"] == "baseline" and not board["model_a"]["retired"]


def take_part(live_server, seed, n=3):
    """Bots of Bradley-Terry strengths, which pass the catch trials (the analysis leaves
    out a participant who fails one), as slow as the clips last (it leaves out faster
    answers too)."""
    call_command("simulate_participants", study=SLUG, n=n, url=live_server.url, pace=1,
                 seed=seed, policy="bt", strengths="model_a=2,model_b=1", stdout=StringIO())


def live_json(url):
    import urllib.request

    with urllib.request.urlopen(f"{url}/arena/{SLUG}.json") as response:
        return json.loads(response.read())


def test_the_leaderboard_page_and_json_are_public_and_computed_in_the_background(
        arena, client, live_server, monkeypatch):
    from studyapp.results import leaderboard

    started = []
    monkeypatch.setattr(leaderboard, "run_job", lambda kind, **params: started.append(params))
    # Nothing computed yet: the page says so and asks for the job once.
    page = client.get(f"/arena/{SLUG}/")
    assert page.status_code == 200 and b"being computed" in page.content
    assert started == [{"name": "arena", "args": ["board", "--study", SLUG]}]
    client.get(f"/arena/{SLUG}.json")
    assert len(started) == 1  # asked for within the period: not again
    take_part(live_server, seed=2)
    call_command("arena", "board", "--study", SLUG, "--bootstrap", "50", stdout=StringIO())
    data = client.get(f"/arena/{SLUG}.json").json()
    assert data["min_votes"] == 4 and data["answers"] == 9
    rows = {row["source"]: row for row in data["sources"]}
    assert set(rows) == {"model_a", "model_b"}
    for row in rows.values():
        assert row["ci_low"] <= row["score"] <= row["ci_high"]
        assert row["votes"] > 0 and row["preliminary"] == (row["votes"] < 4)
    assert rows["model_a"]["anchor"] == "baseline" and rows["model_a"]["vs_baseline"] is None
    versus = rows["model_b"]["vs_baseline"]  # model_b - model_a, with its interval
    assert versus["difference"] == pytest.approx(rows["model_b"]["score"] - rows["model_a"]["score"],
                                                 abs=1e-3)
    assert versus["ci_low"] <= versus["difference"] <= versus["ci_high"]
    html = client.get(f"/arena/{SLUG}/").content.decode()
    assert "model_a" in html and "anchor: baseline" in html and "Votes" in html
    # A session still running never moves the board (one could answer a trial, reload
    # the board and read which sources one was shown): here one bot is put back mid-study.
    from studyapp.survey.models import Participant

    one = Participant.objects.filter(study__slug=SLUG, outcome="completed").first()
    Participant.objects.filter(pk=one.pk).update(outcome="", completed_at=None)
    call_command("arena", "board", "--study", SLUG, "--bootstrap", "50", stdout=StringIO())
    running = client.get(f"/arena/{SLUG}.json").json()
    assert running["answers"] == 6
    assert sum(r["votes"] for r in running["sources"]) < sum(r["votes"] for r in rows.values())
    assert client.get("/arena/no-such-arena/").status_code == 404


@pytest.mark.browser
def test_the_leaderboard_reads_in_a_browser(arena, live_server, page):
    from playwright.sync_api import expect

    call_command("arena", "board", "--study", SLUG, "--bootstrap", "0", stdout=StringIO())
    page.goto(f"{live_server.url}/arena/{SLUG}/")
    expect(page.get_by_role("heading", name="Leaderboard")).to_be_visible()
    rows = page.locator("[data-leaderboard] tbody tr")
    expect(rows).to_have_count(2)
    expect(page.locator("[data-source=model_a]")).to_contain_text("anchor: baseline")
    assert page.evaluate("() => document.documentElement.scrollWidth") <= page.viewport_size["width"]

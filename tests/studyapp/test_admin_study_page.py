"""The admin's study page: progress first, each clip by its id, scoring standards only
where the type has them; Results shows the latest analysis, also one `analyze --out`
wrote from the command line."""

import pytest
from django.core.management import call_command

from studyapp.survey.models import Stimulus, Study
from studyapp.survey.study_types import get_study_type, list_study_types
from tests.studyapp.test_export import build_study

pytestmark = pytest.mark.django_db


@pytest.mark.parametrize("key", list_study_types())
def test_scoring_standards_show_only_for_a_type_that_has_them(admin_client, key):
    study = Study.objects.create_study(key, f"admin-{key.replace('_', '-')}", "Study",
                                       **get_study_type(key).defaults(3))
    text = admin_client.get(f"/admin/survey/study/{study.pk}/change/").content.decode()
    has = Stimulus.Role.EXAMPLE in get_study_type(key).stimulus_roles({})
    assert ("Scoring standards" in text) == has


def test_progress_lists_each_clip_by_its_id(admin_client):
    study = build_study("clip-ids")
    text = admin_client.get(f"/admin/survey/study/{study.pk}/change/").content.decode()
    assert "<th>Clip</th>" in text
    for pk in study.stimuli.values_list("pk", flat=True):
        assert f"<tr><td>{pk}</td>" in text


def test_results_show_an_analysis_written_from_the_command_line(admin_client, settings,
                                                                tmp_path):
    settings.VAR_DIR = tmp_path / "var"
    study = build_study("from-cli")
    page = f"/admin/survey/study/{study.pk}/results/"
    assert "No analysis yet" in admin_client.get(page).content.decode()
    out = tmp_path / "elsewhere"
    call_command("analyze", study=study.slug, out=str(out), bootstrap=20, no_audit=True)
    text = admin_client.get(page).content.decode()
    assert "No analysis yet" not in text and "Analysis of" in text
    shown = admin_client.get(f"{page}report/")
    assert shown.status_code == 200
    assert b"".join(shown.streaming_content) == (out / "report.html").read_bytes()
    # Another study of the same slug later does not show this one's report.
    Study.objects.filter(pk=study.pk).update(slug="renamed")
    again = build_study("from-cli")
    assert "No analysis yet" in admin_client.get(
        f"/admin/survey/study/{again.pk}/results/").content.decode()

"""The admin's plan page beside a study: a form, a background plan, its table and plot."""

import time

import pytest

from studyapp.survey.models import Study


@pytest.mark.django_db(transaction=True)
def test_plan_page_runs_the_plan_in_the_background(admin_client, settings, tmp_path):
    settings.VAR_DIR = tmp_path
    study = Study.objects.create(slug="plan-me", title="Plan me", study_type="pairwise")
    page = f"/admin/survey/study/{study.pk}/plan/"
    shown = admin_client.get(page).content.decode()
    assert "No plan yet" in shown and "service fee" in shown.lower()
    bad = admin_client.post(page, {"effect": "1.5", "clip_sd": "0", "trials": "6",
                                   "participants": "ten", "clips": "2", "studies": "3",
                                   "clip_seconds": "3", "reward_per_hour": "12",
                                   "service_fee": "0.333"})
    assert bad.status_code == 200 and "errorlist" in bad.content.decode()
    started = admin_client.post(page, {"effect": "1.5", "clip_sd": "0", "trials": "6",
                                       "participants": "10,20", "clips": "2", "studies": "3",
                                       "clip_seconds": "3", "reward_per_hour": "12",
                                       "service_fee": "0.333"})
    assert started.status_code == 302
    figure = tmp_path / "plans" / study.slug / "power.png"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not figure.is_file():
        time.sleep(0.3)
    assert figure.is_file(), "the background plan wrote no plot"
    shown = admin_client.get(page).content.decode()
    assert "Plan of" in shown and "<th>power</th>" in shown and "<th>cost</th>" in shown
    png = admin_client.get(f"{page}power.png")
    assert png.status_code == 200 and png["Content-Type"] == "image/png"
    assert f"/admin/survey/study/{study.pk}/plan/" in admin_client.get(
        f"/admin/survey/study/{study.pk}/change/").content.decode()

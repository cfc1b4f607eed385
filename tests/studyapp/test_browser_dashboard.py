"""A real Chromium opens a study's live dashboard as staff: the numbers, the clip
previews, the bots marked, nothing fetched from elsewhere, and a new answer appears
without a reload."""

from io import StringIO
from urllib.parse import urlsplit

import pytest
from django.core.management import call_command
from django.test import Client
from playwright.sync_api import expect

from studyapp.participation.bots import USER_AGENT
from studyapp.survey.models import Participant, Stimulus, TrialItem
from tests.studyapp.conftest import Bot, make_ranking_study
from tests.studyapp.test_browser import snap

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


@pytest.fixture
def study(transactional_db, media_root, clips, settings, tmp_path):
    settings.VAR_DIR = tmp_path / "var"
    settings.STUDY_DASHBOARD_REFRESH_S = 1
    return make_ranking_study(clips, completion_url="https://platform.example/complete?cc=OK",
                              max_participants=5)


def log_in(page, base, next_path):
    from django.contrib.auth.models import User

    User.objects.create_superuser("staff", "staff@example.org", "staff-password")
    page.goto(f"{base}/admin/login/?next={next_path}")
    page.fill("#id_username", "staff")
    page.fill("#id_password", "staff-password")
    page.locator("input[type=submit]").click()
    page.wait_for_url(f"**{next_path}")


def main_judgements(study):
    return TrialItem.objects.judged().filter(
        trial__participant__study=study, trial__kind="main",
        trial__answered_at__isnull=False).count()


def test_the_dashboard_shows_the_study_and_refreshes_itself(page, live_server, study, tmp_path):
    person = Bot(Client(), study)
    person.join(PROLIFIC_PID="person")
    person.finish()
    simulated = Bot(Client(HTTP_USER_AGENT=USER_AGENT), study)
    simulated.join(PROLIFIC_PID="simulated")
    simulated.finish()
    late = Bot(Client(), study)
    late.join(PROLIFIC_PID="late")
    assert Participant.objects.filter(study=study, outcome="completed").count() == 2

    outside = []
    host = urlsplit(live_server.url).netloc

    def only_here(route):
        if urlsplit(route.request.url).netloc != host:
            outside.append(route.request.url)
            return route.abort()
        return route.continue_()

    page.route("**/*", only_here)
    path = f"/admin/survey/study/{study.pk}/dashboard/"
    log_in(page, live_server.url, path)

    expect(page.locator("[data-value=total]")).to_have_text("3")
    expect(page.locator('[data-value="outcome-completed"]')).to_have_text("2")
    expect(page.locator('[data-value="outcome-taking_part"]')).to_have_text("1")
    expect(page.locator("[data-value=bots]")).to_contain_text("1 simulated")
    expect(page.locator("svg.dashboard-timeline rect").first).to_be_visible()
    before = main_judgements(study)
    expect(page.locator("[data-value=judgements-total]")).to_have_text(str(before))
    for stimulus in Stimulus.objects.filter(study=study, role=Stimulus.Role.JUDGED):
        cell = page.locator(f'[data-cell="{stimulus.action}/{stimulus.source}"] '
                            f'[data-value=judgements]')
        n = TrialItem.objects.judged().filter(stimulus__action=stimulus.action,
                                              stimulus__source=stimulus.source,
                                              trial__participant__study=study,
                                              trial__kind="main",
                                              trial__answered_at__isnull=False).count()
        expect(cell).to_have_text(str(n))
    clips = page.locator("[data-clip]")
    expect(clips).to_have_count(Stimulus.objects.filter(study=study).count())
    # Each clip by its id, with a preview that staff can load.
    first = Stimulus.objects.filter(study=study).order_by("action", "source", "pk").first()
    row = page.locator(f'[data-clip="{first.pk}"]')
    expect(row.locator("td").first).to_have_text(str(first.pk))
    poster = row.locator("video").get_attribute("poster")
    assert poster == first.preview_url("png")
    status = page.evaluate("url => fetch(url).then(r => r.status)", poster)
    assert status == 200
    snap(page, "dashboard")

    # A new answer shows up without reloading the page.
    trial = late.participant().current_trial()
    late.trial_page()
    late.answer(late.answer_data(trial))
    assert main_judgements(study) > before
    expect(page.locator("[data-value=judgements-total]")).to_have_text(
        str(main_judgements(study)), timeout=10_000)
    judged = trial.items.filter(role="judged").first().stimulus
    n = TrialItem.objects.judged().filter(stimulus=judged, trial__kind="main",
                                          trial__answered_at__isnull=False).count()
    expect(page.locator(f'[data-clip-judgements="{judged.pk}"]')).to_have_text(str(n))
    expect(page.locator("#dashboard-updated")).to_contain_text("updated")

    # An analysis run from the command line, written elsewhere, appears with its
    # intervals and the blindness audit.
    expect(page.locator("#dash-analysis")).to_contain_text("No analysis yet")
    call_command("analyze", study=study.slug, out=str(tmp_path / "elsewhere"), bootstrap=20,
                 min_time_factor=0.0, stdout=StringIO(), stderr=StringIO())
    expect(page.locator("[data-analysis] tbody tr")).to_have_count(3, timeout=10_000)
    expect(page.locator("[data-analysis]")).to_contain_text("[")
    expect(page.locator("[data-audit=blindness] tbody tr").first).to_be_visible()
    snap(page, "dashboard-analysed")
    assert outside == []


def test_the_study_pages_link_the_dashboard(page, live_server, study):
    log_in(page, live_server.url, f"/admin/survey/study/{study.pk}/change/")
    page.get_by_role("link", name="Live dashboard").click()
    expect(page.locator("h1")).to_contain_text(f"Dashboard of {study.slug}")

"""A real Chromium meets an instructed-response check on the live server: the trial says
in its own words which answer to give; a person who reads it passes, one who does not
fails, and the server grades it."""

import re

import pytest
from playwright.sync_api import expect

from studyapp.survey.models import Participant, Trial
from tests.studyapp.conftest import make_study
from tests.studyapp.test_browser import ALL_WATCHED, snap
from tests.studyapp.test_browser_types import begin, submit_and_wait

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]


def answer(page, study_type: str, obey: bool) -> None:
    """Answer the trial on screen; on an attention check do what its text says (or not)."""
    notice = page.locator(".notice-check")
    said = notice.inner_text() if notice.count() else ""
    if study_type == "pairwise":
        side = "left"
        if said:
            asked = re.search(r"choose \u201c(Left|Right)\u201d", said).group(1).lower()
            side = asked if obey else {"left": "right", "right": "left"}[asked]
        page.keyboard.press("ArrowLeft" if side == "left" else "ArrowRight")
        return
    target, end = None, None
    if said:  # "move the slider of Clip B all the way to the left, to 0, ..."
        label, where = re.search(r"slider of Clip (\w+) all the way to the (left|right)",
                                 said).groups()
        target, end = ord(label) - ord("A"), "0" if where == "left" else "100"
        if not obey:
            end = "50"
    for i in range(page.locator(".judged").count()):
        page.locator(".judged").nth(i).locator("input[type=range]").fill(
            end if i == target else "50")


@pytest.mark.parametrize("study_type", ["pairwise", "mushra"])
def test_a_person_who_reads_the_check_passes_it(page, live_server, transactional_db, media_root,
                                                clips, extra_clips, study_type):
    study = make_study(study_type, clips, extra_clips, instructed_checks=1,
                       trials_per_participant=1)
    for n, obey in enumerate((True, False)):
        page.context.clear_cookies()
        begin(page, f"{live_server.url}/s/{study.slug}/?PROLIFIC_PID=reader-{n}")
        page.get_by_role("button", name="Start").click()
        seen = []
        while "/trial/" in page.url:
            page.wait_for_function(ALL_WATCHED, timeout=15_000)
            notice = page.locator(".notice-check")
            seen.append(notice.count())
            if notice.count():
                expect(notice).to_be_visible()
                expect(notice).to_contain_text("This is an attention check:")
                snap(page, f"desktop-{study_type}-instructed-check")
            answer(page, study_type, obey)
            submit_and_wait(page)
        assert seen == [0, 1]  # never first
        person = Participant.objects.get(external_key=f"PROLIFIC_PID:reader-{n}")
        check = person.trials.get(kind=Trial.Kind.INSTRUCTED)
        assert check.catch_passed is obey
        expect(page.locator("[data-completion-code]")).to_be_visible()

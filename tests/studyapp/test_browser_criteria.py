"""A real Chromium takes studies that ask two questions of the same clips, on the live
server: a rating study through to the export (both questions shown and labelled, the
answer held back until both are given, each stored and exported under its own
criterion) and a ranking with one list per question."""

import pandas as pd
import pytest
from django.core.management import call_command
from playwright.sync_api import expect

from studyapp.survey.models import Participant, Trial
from tests.studyapp.conftest import make_study
from tests.studyapp.test_browser import ALL_WATCHED, snap, trial_id
from tests.studyapp.test_browser_types import begin, submit_and_wait, tokens

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

CRITERIA = [{"key": "naturalness", "question": "How natural is the movement?"},
            {"key": "fit", "question": "How well does it show the action?"}]


def test_chromium_answers_two_questions_per_clip_through_to_the_export(
        page, live_server, transactional_db, media_root, clips, extra_clips, tmp_path):
    study = make_study("rating_reference", clips, extra_clips, criteria=CRITERIA,
                       trials_per_participant=2)
    begin(page, f"{live_server.url}/s/{study.slug}/?PROLIFIC_PID=two-questions")
    page.get_by_role("button", name="Start").click()

    given = {}
    while "/trial/" in page.url:
        page.wait_for_function(ALL_WATCHED, timeout=15_000)
        expect(page.locator(".lede")).to_contain_text("each of the 2 questions below")
        expect(page.locator("#scale-hint")).to_have_text("For each question: 1 = lowest · 5 = highest")
        cards = page.locator(".judged")
        clips_on_screen = tokens(page)
        assert cards.count() == len(clips_on_screen) >= 2
        for i in range(cards.count()):
            legends = cards.nth(i).locator(".question-legend")
            expect(legends).to_have_text([c["question"] for c in CRITERIA])
        submit = page.locator("[data-submit]")
        answers = {}
        # The first question of every clip: still not enough to send.
        for i, token in enumerate(clips_on_screen):
            answers[token] = {"naturalness": 1 + i % 5, "fit": 5 - i % 5}
            scales = cards.nth(i).locator("fieldset.scale")
            expect(scales).to_have_count(2)
            scales.nth(0).locator(".choice").nth(answers[token]["naturalness"] - 1).click()
        expect(submit).to_be_disabled()
        for i, token in enumerate(clips_on_screen):
            cards.nth(i).locator("fieldset.scale").nth(1).locator(".choice").nth(
                answers[token]["fit"] - 1).click()
        expect(submit).to_be_enabled()
        snap(page, "two-questions-trial")
        given[trial_id(page)] = answers
        submit_and_wait(page)

    expect(page.locator("[data-completion-code]")).to_be_visible()
    participant = Participant.objects.get()
    trials = {str(t.pk): t for t in participant.trials.filter(kind=Trial.Kind.MAIN)}
    assert set(given) == set(trials)
    for key, answers in given.items():
        stored = {item.token: item.answers for item in trials[key].items.judged()}
        assert stored == answers

    out = tmp_path / "responses.csv"
    call_command("export_responses", study=study.slug, out=str(out))
    table = pd.read_csv(out)
    expected = {
        (int(key), item.stimulus_id, criterion): value
        for key, answers in given.items() for item in trials[key].items.judged()
        for criterion, value in answers[item.token].items()
    }
    assert len(table) == len(expected) == 2 * sum(len(a) for a in given.values())
    assert sorted(table["criterion"].unique()) == ["fit", "naturalness"]
    got = {(row.trial_id, row.stimulus, row.criterion): row.rating for row in table.itertuples()}
    assert got == expected


def test_chromium_ranks_the_clips_once_per_question(
        page, live_server, transactional_db, media_root, clips, tmp_path):
    study = make_study("ranking", clips, criteria=["naturalness", "fit to the action"],
                       trials_per_participant=1)
    begin(page, f"{live_server.url}/s/{study.slug}/?PROLIFIC_PID=two-rankings")
    page.get_by_role("button", name="Start").click()
    page.wait_for_function(ALL_WATCHED, timeout=15_000)
    panels = page.locator("[data-ranking-panel]")
    expect(panels).to_have_count(2)
    expect(panels.locator("h2")).to_have_text(["Naturalness", "Fit to the action"])
    submit = page.locator("[data-submit]")
    panels.nth(0).get_by_role("button", name="Keep this order").click()
    expect(submit).to_be_disabled()  # the second list is still unranked
    # The second question: the first clip of the list moved to the bottom.
    second = panels.nth(1)
    moved = second.locator(".rank-row").first.get_attribute("data-clip")
    for _ in range(2):
        second.locator(f".rank-row[data-clip='{moved}'] [data-move='1']").click()
    order = [second.locator(".rank-row").nth(i).get_attribute("data-clip") for i in range(3)]
    first = [panels.nth(0).locator(".rank-row").nth(i).get_attribute("data-clip") for i in range(3)]
    assert order == first[1:] + first[:1]
    expect(submit).to_be_enabled()
    submit_and_wait(page)

    expect(page.locator("[data-completion-code]")).to_be_visible()
    trial = Trial.objects.get(kind=Trial.Kind.MAIN)
    stored = {item.token: item.answers for item in trial.items.judged()}
    assert stored == {token: {"naturalness": first.index(token) + 1,
                              "fit_to_the_action": order.index(token) + 1} for token in first}

"""The adversary of the crowd-integrity review, end to end: a script that never watches.

It enters a Prolific study with made-up ids, fetches only the in-browser player's
payloads, picks the broken clip of a catch trial as the one whose bones stretch most (the
attack that recognised shaken catch clips from their numbers), and answers a repeated
trial as it answered the earlier one whose bytes it has seen (a hash of what it fetched).
Each defence takes one of its tricks away: the link for another study is refused, catch
clips keep every bone's length (and are kept like the judged clips in their numbers), and
every delivery has bytes of its own. What is left is guessing, so such bots mostly fail
the attention checks, and each that fails gets that outcome's code, never the completed
one.
"""

import hashlib
from pathlib import Path

import numpy as np
import pytest

from rendering.player import read
from studyapp.survey.models import Stimulus, Study, Trial
from studyapp.stimuli.build import build_stimuli
from studyapp.stimuli.config import load_config

pytestmark = pytest.mark.django_db
STUDY_ID = "60aaca280709ee40ec37d488"
CODES = {"completed": "C0MPL3TE", "failed_attention": "FA1LED00", "no_consent": "N0C0NSNT"}
PROLIFIC = {"platform": "prolific", "codes": CODES, "prolific_study_id": STUDY_ID}
ADVERSARIES = 9
DEMO = Path(__file__).resolve().parents[2] / "studies" / "demo" / "ranking.yaml"


@pytest.fixture
def study(media_root, tmp_path):
    """The demo's ranking study as the build makes it, small and played in the page, on
    Prolific with four catch trials and two repeats per participant."""
    config = load_config(DEMO, ["render.size=48", "render.player=webgl", "frames=20"])
    built = build_stimuli(config, tmp_path / "b", cache=tmp_path / "cache").study
    Study.objects.filter(pk=built.pk).update(
        crowd=PROLIFIC, catch_trials=4, repeat_trials=2, instructed_checks=0,
        trials_per_participant=4, max_failed_catch=1)
    return Study.objects.get(pk=built.pk)


def stretch(payload: bytes) -> float:
    """Return how far the figure's bones stretch over the clip: the largest relative
    range of one bone's length (what told shaken catch clips from judged ones)."""
    motion = read(payload)
    positions, parents = motion["positions"], motion["parents"]
    bones = [j for j in range(motion["joints"]) if parents[j] >= 0]
    lengths = np.linalg.norm(positions[:, bones] - positions[:, parents[bones]], axis=-1)
    return float((np.ptp(lengths, axis=0) / np.maximum(np.median(lengths, axis=0), 1e-6)).max())


class Adversary:
    """Answer from the bytes alone: bone stretch for catch trials, hashes for repeats."""

    def __init__(self, bot, rng):
        self.bot, self.rng = bot, rng
        self.answers = {}  # sha256 of a trial's payloads, in screen order -> ranks given
        self.caught = 0  # catch trials where the stretched clip was the broken one

    def payloads(self, trial) -> list[bytes]:
        out = []
        for item in trial.items.order_by("position"):
            response = self.bot.client.get(item.clip_url("motion"))
            assert response.status_code == 200
            out.append(b"".join(response.streaming_content))
        return out

    def ranks_for(self, trial, payloads) -> dict:
        seen = hashlib.sha256(b"".join(payloads)).hexdigest()
        if seen in self.answers:  # a repeat whose bytes it has seen: answer as before
            return self.answers[seen]
        stretched = int(np.argmax([stretch(p) for p in payloads]))
        others = [p for p in range(len(payloads)) if p != stretched]
        order = list(self.rng.permutation(others)) + [stretched]  # "broken" ranked last
        ranks = {int(position): rank + 1 for rank, position in enumerate(order)}
        if trial.kind == Trial.Kind.CATCH:
            broken = trial.items.get(stimulus__role=Stimulus.Role.CATCH).position
            self.caught += stretched == broken
        self.answers[seen] = ranks
        return ranks

    def play(self):
        response = None
        while (trial := self.bot.participant().current_trial()) is not None:
            self.bot.trial_page(watch=False)  # the page, never its videos
            ranks = self.ranks_for(trial, self.payloads(trial))
            response = self.bot.answer(self.bot.answer_data(trial, ranks=ranks), follow=True)
            assert response.status_code == 200
        return response


@pytest.mark.slow
def test_a_bot_that_reads_only_bytes_fails_attention_and_is_paid_nothing(study, make_bot,
                                                                       monkeypatch):
    # Seeded sessions, so which guesses land does not change from run to run.
    seeds = iter(range(1, 100))
    monkeypatch.setattr("studyapp.survey.models.participation.secrets.randbits", lambda bits: next(seeds))
    assert study.player and study.max_failed_catch == 1  # fails after two failed checks
    rng = np.random.default_rng(0)
    caught = catches = failed = 0
    for k in range(ADVERSARIES):
        pid = f"{k:02d}" + "f00d" * 5 + "aa"
        # Made-up ids for another study: refused at the door, no place taken.
        door = make_bot(study)
        door.enter(PROLIFIC_PID=pid, STUDY_ID="1" * 24, SESSION_ID=pid[::-1])
        door.consent()
        assert not study.participants.filter(external_ids__PROLIFIC_PID=pid).exists()
        # Made-up person and session for this study: let in (review flags them later).
        bot = make_bot(study)
        bot.enter(PROLIFIC_PID=pid, STUDY_ID=STUDY_ID, SESSION_ID=pid[::-1])
        bot.consent()
        bot.start()
        adversary = Adversary(bot, rng)
        page = adversary.play().content.decode()
        person = bot.participant()
        # Paid only as what it is: a guess that happened to pass is paid as completed,
        # every failed one gets the failed code and never the completed one.
        assert person.outcome in ("failed_attention", "completed")
        if person.outcome == "failed_attention":
            failed += 1
            assert person.completion_code == CODES["failed_attention"]
            assert CODES["completed"] not in page
        # Its repeat answers matched nothing it had hashed: every delivery is new bytes.
        repeats = person.trials.filter(kind=Trial.Kind.REPEAT).count()
        assert repeats == 2 and len(adversary.answers) == person.trials.count()
        caught += adversary.caught
        catches += person.trials.filter(kind=Trial.Kind.CATCH).count()
    # Bone stretch no longer finds the broken clip (it did every time when catch clips
    # were shaken): about one in three, as a guess among three would, so most such bots
    # fail two checks (a blind guesser passes three of four about one time in nine).
    assert catches == 4 * ADVERSARIES and caught <= catches // 2, (caught, catches)
    assert failed >= (ADVERSARIES + 1) // 2, failed


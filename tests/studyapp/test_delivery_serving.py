"""Every delivery of a clip is bytes of its own: a bot that hashes what it is sent cannot
recognise a repeated trial's clips or another participant's catch clip, while byte ranges
of one delivery agree and the server still knows what was fetched whole."""

import hashlib
import logging

import pytest

from analysis.clip_features import content_keys, same_content
from studyapp.stimuli import media
from studyapp.survey.models import Stimulus, Trial, TrialItem
from tests.studyapp.conftest import make_study
from tests.studyapp.rendered_clips import render_clips

pytestmark = pytest.mark.django_db
EXTS = ("mp4", "png", "motion")


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    return render_clips(tmp_path_factory.mktemp("served"))


def fetch(client, item, ext, **headers):
    response = client.get(item.clip_url(ext), **headers)
    assert response.status_code in (200, 206), response.status_code
    return response, b"".join(response.streaming_content)


def session_items(make_bot, study):
    """Take a study as a participant; return its trials' items, in session order."""
    bot = make_bot(study)
    bot.join()
    bot.finish()
    person = bot.participant()
    assert person.completed_at is not None
    return bot, [list(t.items.select_related("stimulus").order_by("position"))
                 for t in Trial.objects.filter(participant=person).order_by("index")]


def test_a_bot_that_hashes_deliveries_matches_no_repeat_and_no_catch_clip(
        rendered, media_root, make_bot):
    # One catch clip for everyone: the case where hashes could be shared between bots.
    clips = [c for c in rendered if c.role == "judged"] + [
        next(c for c in rendered if c.role == "catch")]
    study = make_study("ranking", clips, slug="hashing", catch_trials=1, repeat_trials=1,
                       trials_per_participant=2)
    seen = {}  # sha256 -> (participant, stimulus, ext): what a ring of bots would share
    for k in range(3):
        bot, trials = session_items(make_bot, study)
        kinds = [items[0].trial.kind for items in trials]
        assert Trial.Kind.REPEAT in kinds and Trial.Kind.CATCH in kinds
        for items in trials:
            for item in items:
                for ext in EXTS:
                    response, body = fetch(bot.client, item, ext)
                    digest = hashlib.sha256(body).hexdigest()
                    assert digest not in seen, (seen[digest], (k, item.stimulus_id, ext))
                    seen[digest] = (k, item.stimulus_id, ext)
    repeats = TrialItem.objects.filter(trial__kind=Trial.Kind.REPEAT)
    catches = TrialItem.objects.filter(stimulus__role=Stimulus.Role.CATCH)
    assert repeats.count() == 3 * 3 and catches.values("stimulus").distinct().count() == 1
    # What they show is the same clip, as a viewer would see: content, not hashes.
    item = repeats.first()
    original = TrialItem.objects.get(trial=item.trial.repeat_of, stimulus=item.stimulus)
    files = [{ext: ({}, fetch(bot.client, i, ext)[1]) for ext in EXTS} for i in (item, original)]
    keys = [content_keys(f) for f in files]
    assert all(same_content(ext, keys[0][ext], keys[1][ext]) for ext in EXTS)
    assert files[0]["mp4"][1] != files[1]["mp4"][1]


def test_byte_ranges_of_one_delivery_agree_and_its_etag_is_its_own(rendered, media_root,
                                                                   make_bot, client):
    study = make_study("ranking", [c for c in rendered if c.role == "judged"], slug="ranges",
                       repeat_trials=1, trials_per_participant=2)
    bot, trials = session_items(make_bot, study)
    item = trials[0][0]
    twin = TrialItem.objects.filter(stimulus=item.stimulus).exclude(pk=item.pk).first()
    stored = open(media_root / item.stimulus.video, "rb").read()
    full, whole = fetch(client, item, "mp4")
    assert len(whole) == len(stored) == int(full["Content-Length"]) and whole != stored
    head, first = fetch(client, item, "mp4", HTTP_RANGE="bytes=0-999")
    tail_response, rest = fetch(client, item, "mp4", HTTP_RANGE="bytes=1000-")
    assert head.status_code == tail_response.status_code == 206
    assert first + rest == whole  # a seek in one delivery reads the same bytes
    assert client.head(item.clip_url("mp4"))["Content-Length"] == str(len(stored))
    assert client.get(item.clip_url("mp4"), HTTP_IF_NONE_MATCH=full["ETag"]).status_code == 304
    partial, body = fetch(client, item, "mp4", HTTP_RANGE="bytes=0-9", HTTP_IF_RANGE=full["ETag"])
    assert partial.status_code == 206 and body == whole[:10]
    other, theirs = fetch(client, twin, "mp4")
    assert other["ETag"] != full["ETag"] and theirs != whole
    # The deliveries' seeds are the site's: another secret, other bytes and ETags.
    assert media.delivery_seed(item.token) != media.delivery_seed(twin.token)


def test_a_delivery_fetched_in_ranges_counts_as_fetched_whole(rendered, media_root, make_bot):
    study = make_study("ranking", [c for c in rendered if c.role == "judged"], slug="fetched")
    bot = make_bot(study)
    bot.join()
    bot.trial_page(watch=False)
    item = bot.participant().current_trial().items.first()
    size = int(bot.client.head(item.clip_url("mp4"))["Content-Length"])
    fetch(bot.client, item, "mp4", HTTP_RANGE=f"bytes=0-{size // 2}")
    fetch(bot.client, item, "mp4", HTTP_RANGE=f"bytes={size // 2 + 1}-")
    item.refresh_from_db()
    assert item.fetched["mp4"] == [[0, size - 1]] and item.fetched_at is not None


def test_a_file_the_transformation_cannot_read_is_sent_as_stored(clips, media_root, make_bot,
                                                                 caplog):
    """The test clips of other tests come straight from ffmpeg: no filler, no padding.
    They are served as stored, with a warning, and the blindness audit says so."""
    study = make_study("ranking", clips, slug="unpadded")
    bot = make_bot(study)
    bot.join()
    bot.trial_page(watch=False)
    item = bot.participant().current_trial().items.first()
    stored = open(media_root / item.stimulus.video, "rb").read()
    from studyapp.stimuli import media

    media.SENT_AS_STORED.clear()  # these clips were served by earlier tests too
    with caplog.at_level(logging.WARNING, logger="studyapp.stimuli.media"):
        assert fetch(bot.client, item, "mp4")[1] == stored
        assert fetch(bot.client, item, "mp4")[1] == stored  # again: not logged again
    warned = "is sent as stored, the same bytes for every delivery"
    assert caplog.text.count(warned) == 1
    poster = open(media_root / item.stimulus.poster, "rb").read()
    assert fetch(bot.client, item, "png")[1] == poster

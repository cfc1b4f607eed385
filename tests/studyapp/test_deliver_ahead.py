"""Clips written ahead by their trial page (media.deliver_ahead) and nginx's location that
sends them without asking the app: which files a page writes, when, and what the config
says. tests/studyapp/test_accel.py runs the same against a real nginx."""

import pytest

from tests.studyapp.conftest import make_ranking_study

pytestmark = pytest.mark.django_db


def written(media_root) -> set[str]:
    folder = media_root / "deliveries"
    return {p.name for p in folder.iterdir()} if folder.exists() else set()


@pytest.fixture
def behind_nginx(settings, media_root):
    settings.STUDY_ACCEL_REDIRECT = "/protected-media/"
    return media_root


def test_a_trial_page_writes_its_videos_and_posters_before_it_is_shown(behind_nginx, clips,
                                                                        make_bot, settings):
    from studyapp.survey.models import Trial

    study = make_ranking_study(clips)
    bot = make_bot(study)
    bot.join()
    trial = Trial.objects.filter(participant=bot.participant(), shown_at__isnull=False).get()
    names = written(behind_nginx)
    expected = set()
    for item in trial.items.select_related("stimulus"):
        expected.add(f"{item.token}.mp4")
        if item.stimulus.poster:
            expected.add(f"{item.token}.png")
        assert f"{item.token}.motion" not in names  # no payload: the page plays videos
    assert expected and expected <= names
    # Nothing else: the trials to come are written when their pages are sent.
    assert names == expected


def test_nothing_is_written_without_nginx_or_when_switched_off(clips, make_bot, media_root,
                                                               settings):
    study = make_ranking_study(clips)
    make_bot(study).join()  # no STUDY_ACCEL_REDIRECT: the view streams
    assert written(media_root) == set()
    settings.STUDY_ACCEL_REDIRECT = "/protected-media/"
    settings.STUDY_DELIVER_AHEAD = False
    make_bot(study).join()
    assert written(media_root) == set()


def test_a_failed_write_leaves_the_page_and_the_view_to_try_again(behind_nginx, clips, make_bot,
                                                                   monkeypatch, caplog):
    from studyapp.stimuli import media

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(media, "write_delivery", full_disk)
    study = make_ranking_study(clips)
    bot = make_bot(study)
    bot.join()
    page = bot.trial_page(watch=False)
    assert page.status_code == 200
    assert "could not write delivery" in caplog.text and "No space left" in caplog.text


def test_the_clip_location_is_in_the_config_unless_switched_off_or_in_a_bucket(settings):
    from studyapp.participation.proxy_log import nginx_config

    def config(**kw):
        return nginx_config(listen="127.0.0.1:8080", upstream="127.0.0.1:8000",
                            media_root="/srv/media", fetch_log_path="/var/log/fetches.log",
                            run_dir="/run/study", **kw)

    ahead = config()
    assert 'location ~ "^/c/(?<delivery>[A-Za-z0-9_-]{8,64}\\.(?:mp4|png|motion))$"' in ahead
    assert "try_files /deliveries/$delivery @app;" in ahead and "root /srv/media;" in ahead
    assert "location @app {" in ahead and "etag off;" in ahead
    assert "/c/" not in config(ahead=False)
    assert "/c/" not in config(s3_endpoint="https://bucket.example.org")


def test_the_direct_locations_log_lines_are_witnesses():
    from studyapp.participation.fetch_log import parse_line
    from studyapp.participation.proxy_log import witness_of

    token = "AbCdEfGh12345678"
    # After try_files nginx logs the file it sent.
    found = witness_of(f"1796474588.570 200 1910 OK /deliveries/{token}.mp4 -")
    assert found[0] == token and parse_line(found[1])[:4] == ("mp4", 0, 1909, 1910)


def test_the_command_leaves_the_clip_location_out_when_asked(tmp_path, settings):
    import io

    from django.core.management import call_command

    settings.STUDY_ACCEL_REDIRECT = "/protected-media/"

    def run(*extra):
        out = io.StringIO()
        call_command("nginx_config", "--run-dir", str(tmp_path), "--fetch-log",
                     str(tmp_path / "fetches.log"), *extra, stdout=out)
        return out.getvalue()

    assert "try_files /deliveries/$delivery @app;" in run()
    assert "/c/" not in run("--no-ahead")
    settings.STUDY_DELIVER_AHEAD = False
    assert "/c/" not in run()

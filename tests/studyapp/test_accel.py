"""Clips sent by a real nginx (X-Accel-Redirect), its access log read into fetch witnesses.

gunicorn (production settings, ``STUDY_ACCEL_REDIRECT``) behind Debian's nginx configured
by ``manage.py nginx_config``, as ``make serve`` starts them; the test database is
theirs, so this runs on SQLite and on PostgreSQL alike.
"""

import http.client
import os
import secrets
import threading
import time
from pathlib import Path

import pytest
from django.core.management import call_command

from benchmarks.loadtest import Participant
from benchmarks.server import NGINX, Server, nginx, server_env
from tests.studyapp.conftest import make_ranking_study, require_service
from tests.studyapp.test_faults import database_url

pytestmark = [pytest.mark.slow, pytest.mark.django_db(transaction=True)]


@pytest.fixture
def stack(tmp_path, media_root, settings):
    require_service(Path(NGINX).exists(), f"nginx ({NGINX})")
    var = tmp_path / "var"
    settings.MEDIA_ROOT = var / "media"
    settings.SECRET_KEY = secrets.token_urlsafe(50)  # the server's: the same delivery bytes
    settings.STUDY_FETCH_LOG_URL = ""  # witnesses in the spool this process reads too
    settings.STUDY_FETCH_SPOOL = var / "fetches"
    settings.STUDY_ACCEL_REDIRECT = "/protected-media/"
    env = server_env(database_url(), var, STUDY_ACCEL_REDIRECT="/protected-media/", STUDY_CACHE_URL="",
                     STUDY_FETCH_LOG_URL="")
    env["DJANGO_SECRET_KEY"] = settings.SECRET_KEY
    app = Server(env, workers=2, settings="benchmarks.loadtest_settings",
                 log=tmp_path / "gunicorn.log")
    app.collectstatic()
    app.start()
    proxy = nginx(env, tmp_path / "nginx", f"127.0.0.1:{app.port}")
    proxy.start()
    yield app, proxy, tmp_path / "nginx" / "fetches.log"
    proxy.stop()
    app.stop()


def get(port, path, headers=None):
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
    try:
        connection.request("GET", path, headers=headers or {})
        response = connection.getresponse()
        return response.status, dict(response.getheaders()), response.read()
    finally:
        connection.close()


def answered(trial) -> bool:
    from studyapp.survey.models import Trial

    return Trial.objects.filter(pk=int(trial), answered_at__isnull=False).exists()


def test_nginx_sends_each_delivery_and_only_whole_fetches_count(clips, stack):
    from studyapp.stimuli import media
    from studyapp.survey.models import TrialItem

    app, proxy, fetches = stack
    study = make_ranking_study(clips, trials_per_participant=3)
    bot = Participant(proxy.url, study.slug, "accel-1")
    bot.enter()
    bot.consent()
    bot.start()
    first, second = bot.clips()[:2]

    status, headers, body = get(proxy.port, first)
    assert status == 200
    item = TrialItem.objects.select_related("stimulus").get(token=Path(first).stem)
    with open(Path(media.default_storage.path(item.stimulus.video)), "rb") as f:
        stored = f.read()
    assert body == media.delivered_bytes(stored, "mp4", media.delivery_seed(item.token))
    seen = " ".join(f"{k}: {v}" for k, v in headers.items()).lower()
    assert "x-accel" not in seen and "protected" not in seen and "deliveries" not in seen
    assert "etag" not in seen and headers.get("Content-Type") == "video/mp4"
    assert headers["Cache-Control"] == "private, max-age=86400"
    assert headers.get("Last-Modified", "Thu, 01 Jan 1970 00:00:00 GMT").endswith("1970 00:00:00 GMT")

    # Straight from gunicorn: an empty body and the header that nginx consumes.
    status, headers, body = get(app.port, first)
    assert (status, body, headers["X-Accel-Redirect"]) == (200, b"", f"/protected-media/{item.token}.mp4")
    # The internal location is not reachable from outside.
    assert get(proxy.port, f"/protected-media/{item.token}.mp4")[0] == 404

    status, headers, body = get(proxy.port, second, {"Range": "bytes=0-99"})
    assert (status, len(body)) == (206, 100)

    call_command("follow_fetches", "--log", str(fetches), "--once")
    from studyapp.participation import fetch_log

    items = list(TrialItem.objects.filter(token__in=[Path(first).stem, Path(second).stem]))
    fetch_log.witness(items)
    by_token = {i.token: i for i in items}
    assert by_token[Path(first).stem].fetched_at is not None  # whole: counts as fetched
    assert by_token[Path(second).stem].fetched_at is None  # 100 bytes: does not
    assert by_token[Path(second).stem].fetched == {"mp4": [[0, 99]]}

    # Through the pages: answers taken after whole fetches, refused after half of each clip.
    from studyapp.participation import proxy_log

    stop = threading.Event()
    follower = threading.Thread(target=proxy_log.follow, args=(fetches,),
                                kwargs={"flush_every": 0, "stop": stop.is_set})
    follower.start()
    try:
        watcher = Participant(proxy.url, study.slug, "accel-watcher")
        watch = watcher.watch

        def watch_then_press():
            # A bot answers the instant the clips' time is up, even when the last byte came
            # just then; a person presses some 200 ms after the clip. nginx's log is read
            # every 50 ms, so the bot waits as a person would.
            watch()
            time.sleep(0.2)

        watcher.watch = watch_then_press
        watcher.enter()
        watcher.consent()
        watcher.start()
        while watcher.on_trial():
            watcher.answer()  # every clip whole through nginx, then its playing time
        assert watcher.at.endswith("/done/")
        assert all(status == 302 for _, status, _ in watcher.submits)

        skipper = Participant(proxy.url, study.slug, "accel-skipper")
        skipper.enter()
        skipper.consent()
        skipper.start()
        for url in skipper.clips():  # the first 100 bytes of each clip
            get(proxy.port, url, {"Range": "bytes=0-99"})
        time.sleep(0.6)  # as long as they play, and more
        data = skipper.answer_data()
        status, _ = skipper.post(skipper.path("trial"), data)
        assert status == 400  # the trial again, with what is missing: not taken
        assert not answered(data["trial"])
        for url in skipper.clips():  # the rest of each clip
            get(proxy.port, url, {"Range": "bytes=100-"})
        time.sleep(0.3)
        status, _ = skipper.post(skipper.path("trial"), data)
        assert status == 302 and answered(data["trial"])
    finally:
        stop.set()
        follower.join(10)


def test_the_page_writes_its_clips_ahead_and_nginx_sends_them_without_the_app(clips, stack):
    """The trial page's request writes its clips' delivery files; nginx sends them with no
    app worker asked (here: with gunicorn stopped), and its log still makes the witness."""
    from studyapp.participation import fetch_log
    from studyapp.stimuli import media
    from studyapp.survey.models import TrialItem

    app, proxy, fetches = stack
    study = make_ranking_study(clips, trials_per_participant=3)
    bot = Participant(proxy.url, study.slug, "ahead-1")
    bot.enter()
    bot.consent()
    bot.start()
    urls = bot.clips()
    tokens = [Path(url).stem for url in urls]
    deliveries = Path(media.default_storage.path(media.DELIVERIES))
    assert all((deliveries / f"{t}.mp4").exists() for t in tokens)  # before any fetch
    app.stop()  # from here on only nginx answers

    status, headers, body = get(proxy.port, urls[0])
    item = TrialItem.objects.select_related("stimulus").get(token=tokens[0])
    with open(Path(media.default_storage.path(item.stimulus.video)), "rb") as f:
        stored = f.read()
    assert status == 200
    assert body == media.delivered_bytes(stored, "mp4", media.delivery_seed(item.token))
    seen = " ".join(f"{k}: {v}" for k, v in headers.items()).lower()
    assert "etag" not in seen and "deliveries" not in seen and "x-accel" not in seen
    assert headers.get("Content-Type") == "video/mp4"
    assert headers["Cache-Control"] == "private, max-age=86400"
    assert headers.get("Last-Modified", "Thu, 01 Jan 1970 00:00:00 GMT").endswith("1970 00:00:00 GMT")
    status, _, body = get(proxy.port, urls[1], {"Range": "bytes=0-99"})
    assert (status, len(body)) == (206, 100)
    # No file (a token never written ahead): the clip view is asked, and it is down.
    assert get(proxy.port, "/c/AAAAAAAAAAAAAAAAAAAA.mp4")[0] == 502
    assert get(proxy.port, "/c/x.mp4")[0] != 200  # not a token: the app's 404 route

    call_command("follow_fetches", "--log", str(fetches), "--once")
    items = list(TrialItem.objects.filter(token__in=tokens[:2]))
    fetch_log.witness(items)
    by_token = {i.token: i for i in items}
    assert by_token[tokens[0]].fetched_at is not None  # whole, from the direct location
    assert by_token[tokens[1]].fetched_at is None
    assert by_token[tokens[1]].fetched == {"mp4": [[0, 99]]}


def test_nginx_config_command_names_the_internal_location_and_its_log(tmp_path, settings):
    from io import StringIO

    settings.STUDY_ACCEL_REDIRECT = "/protected-media/"
    out = StringIO()
    call_command("nginx_config", "--run-dir", str(tmp_path), "--fetch-log",
                 str(tmp_path / "f.log"), "--listen", "127.0.0.1:9", stdout=out)
    text = out.getvalue()
    assert "location /protected-media/ {" in text and "internal;" in text
    assert f"access_log {tmp_path / 'f.log'} study_fetch;" in text
    assert f"alias {Path(settings.MEDIA_ROOT) / 'deliveries'}/;" in text
    assert "ssl" not in text
    out = StringIO()
    call_command("nginx_config", "--run-dir", str(tmp_path), "--fetch-log", str(tmp_path / "f.log"),
                 "--listen", "0.0.0.0:443", "--tls-cert", "/c.pem", "--tls-key", "/k.pem",
                 "--real-ip-from", "10.0.0.2", stdout=out)
    text = out.getvalue()
    assert "listen 0.0.0.0:443 ssl;" in text and "ssl_certificate_key /k.pem;" in text
    assert "set_real_ip_from 10.0.0.2;" in text and "real_ip_header X-Forwarded-For;" in text


def test_only_responses_sent_whole_become_witnesses():
    from studyapp.participation.fetch_log import parse_line
    from studyapp.participation.proxy_log import witness_of

    token = "AbCdEfGh12345678"
    whole = witness_of(f"1796474588.570 200 1910 OK /protected-media/{token}.mp4 -")
    assert whole[0] == token and parse_line(whole[1])[:4] == ("mp4", 0, 1909, 1910)
    ranged = witness_of(f"1796474588.5 206 100 OK /protected-media/{token}.mp4 bytes 100-199/1910")
    assert parse_line(ranged[1])[:4] == ("mp4", 100, 199, 1910)
    assert parse_line(ranged[1])[4] == pytest.approx(1796474588.5)
    for line in (
        f"1796474588.5 200 900 - /protected-media/{token}.mp4 -",  # cut off
        f"1796474588.5 206 50 - /protected-media/{token}.mp4 bytes 100-199/1910",  # cut off
        f"1796474588.5 206 100 OK /protected-media/{token}.mp4 bytes 0-9/1910",  # sizes disagree
        f"1796474588.5 206 300 OK /protected-media/{token}.mp4 -",  # several ranges at once
        f"1796474588.5 304 0 OK /protected-media/{token}.mp4 -",
        f"1796474588.5 200 0 OK /protected-media/{token}.mp4 -",  # HEAD
        f"1796474588.5 200 1910 OK /protected-media/{token}.png -",  # a poster
        "1796474588.5 200 1910 OK /protected-media/tok%24en.mp4 -",  # not a token
        "garbage",
    ):
        assert witness_of(line) is None, line


def test_the_log_is_read_once_from_where_it_stopped_and_anew_after_rotation(tmp_path, settings):
    from studyapp.participation import fetch_log
    from studyapp.participation.proxy_log import read_new

    settings.STUDY_FETCH_LOG_URL = ""
    settings.STUDY_FETCH_SPOOL = tmp_path / "spool"
    log = tmp_path / "fetches.log"
    line = "1796474588.5 200 1910 OK /protected-media/{}.mp4 -\n"
    log.write_text(line.format("tokenAAAA") + line.format("tokenBBBB")[:20])  # one being written
    assert read_new(log) == 1
    assert read_new(log) == 0  # nothing new (the half line waits)
    with open(log, "a") as f:
        f.write(line.format("tokenBBBB")[20:])
    assert read_new(log) == 1
    log.rename(tmp_path / "fetches.log.1")  # rotated: a new file, read from its start
    log.write_text(line.format("tokenCCCC"))
    assert read_new(log) == 1
    assert set(fetch_log.spool().tokens()) == {"tokenAAAA", "tokenBBBB", "tokenCCCC"}


@pytest.fixture(scope="module")
def built_clips(tmp_path_factory):
    from tests.studyapp.rendered_clips import render_clips

    return render_clips(tmp_path_factory.mktemp("audited"), catch_per_action=3)


def test_the_deep_blindness_audit_passes_through_nginx(built_clips, stack, tmp_path):
    """What a browser receives from nginx (sizes, headers, boxes, padding, hashes) tells
    no source apart and recognises no repeated delivery: each has bytes of its own."""
    from tests.studyapp.test_audit import audit

    app, proxy, _ = stack
    study = make_ranking_study(built_clips, slug="own-bytes", catch_trials=1)
    result, text, error = audit(study, proxy.url, tmp_path)
    assert error is None, text
    assert result["source: delivery"]["passed"] and result["catch: delivery"]["passed"]
    hashes = result["deliveries: hashes"]
    assert hashes["passed"] and hashes["n"] == 2 * len(built_clips)


def test_nginx_fetches_a_bucket_object_with_the_presigned_query_and_hides_s3(tmp_path):
    """The S3 location of nginx_config in a real nginx, with a stand-in app (answers
    X-Accel-Redirect as the clip view does with S3) and a stand-in bucket host (answers
    the signed path with S3's headers; records what it was asked)."""
    import http.server

    from benchmarks.server import Proxy, free_port
    from studyapp.participation.proxy_log import nginx_config, witness_of

    require_service(Path(NGINX).exists(), f"nginx ({NGINX})")
    body = bytes(range(256)) * 40
    token = "S3tokenABCDEFGH1"
    asked = []

    class Bucket(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            asked.append((self.path, dict(self.headers)))
            self.send_response(200)
            for name, value in (("Content-Type", "video/mp4"), ("ETag", '"abc"'),
                                ("Last-Modified", "Sat, 05 Dec 2026 10:00:00 GMT"),
                                ("x-amz-request-id", "R1"), ("x-amz-id-2", "I2"),
                                ("Server", "AmazonS3"), ("Content-Length", str(len(body)))):
                self.send_header(name, value)
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    class App(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            self.send_response(200)
            self.send_header("X-Accel-Redirect", f"/protected-media/s3/bucket/media/deliveries/"
                                                 f"{token}.mp4?Signature=s%2Fg&Expires=9")
            self.send_header("Content-Length", "0")
            self.end_headers()

        def log_message(self, *args):
            pass

    servers = [http.server.ThreadingHTTPServer(("127.0.0.1", 0), cls) for cls in (Bucket, App)]
    for server in servers:
        threading.Thread(target=server.serve_forever, daemon=True).start()
    bucket, app = (f"127.0.0.1:{s.server_address[1]}" for s in servers)
    port = free_port()
    config = nginx_config(listen=f"127.0.0.1:{port}", upstream=app, media_root=tmp_path,
                          fetch_log_path=tmp_path / "fetches.log", run_dir=tmp_path,
                          workers="1", s3_endpoint=f"http://{bucket}",
                          user="root" if os.geteuid() == 0 else "")
    (tmp_path / "nginx.conf").write_text(config)
    proxy = Proxy([NGINX, "-p", str(tmp_path), "-c", str(tmp_path / "nginx.conf"), "-e",
                   str(tmp_path / "error.log"), "-g", "daemon off;"], port)
    proxy.start()
    try:
        status, headers, got = get(port, f"/c/{token}.mp4", {"Cookie": "sessionid=secret"})
    finally:
        proxy.stop()
        for server in servers:
            server.shutdown()
    assert status == 200 and got == body
    seen = " ".join(f"{k}: {v}" for k, v in headers.items()).lower()
    for leak in ("amz", "bucket", "etag", "s3", "signature", "10:00:00"):
        assert leak not in seen, leak
    path, sent = asked[0]
    assert path == f"/bucket/media/deliveries/{token}.mp4?Signature=s%2Fg&Expires=9"
    assert sent["Host"] == bucket and "Cookie" not in sent
    lines = (tmp_path / "fetches.log").read_text().splitlines()
    assert witness_of(lines[-1])[0] == token  # sent whole: a witness

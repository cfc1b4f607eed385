"""Stimulus files on S3-compatible storage (django-storages), against moto in-process.

The storage entry is the one ``studyapp.settings`` builds from ``STUDY_S3_*``; clips go
in through ``register_clips`` and come out through ``/c/<token>.mp4`` as on disk.
"""

import os
import subprocess
import sys
from pathlib import Path

import boto3
import moto
import pytest
from django.core.files.storage import FileSystemStorage, default_storage
from storages.backends.s3 import S3File, S3Storage

from studyapp.settings import s3_storage_from_env
from tests.studyapp.conftest import make_ranking_study, shown_item

ROOT = Path(__file__).resolve().parents[2]
BUCKET = "study-media"
PREFIX = "media"


@pytest.fixture
def s3(settings, monkeypatch, media_root):
    """Point ``default_storage`` at a moto bucket; return the boto3 client."""
    for name in ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_SESSION_TOKEN"):
        monkeypatch.setenv(name, "testing")
    monkeypatch.setenv("AWS_DEFAULT_REGION", "us-east-1")
    with moto.mock_aws():
        client = boto3.client("s3", region_name="us-east-1")
        client.create_bucket(Bucket=BUCKET)
        entry = s3_storage_from_env({"STUDY_S3_BUCKET": BUCKET, "STUDY_S3_REGION": "us-east-1"})
        # pytest-django's settings fixture sends setting_changed: Django drops the
        # cached storages and default_storage is built again from the new STORAGES.
        settings.STORAGES = {**settings.STORAGES, "default": entry}
        assert isinstance(default_storage, S3Storage)
        yield client


def keys(client):
    return sorted(o["Key"] for o in client.list_objects_v2(Bucket=BUCKET).get("Contents", []))


@pytest.fixture
def uploads(monkeypatch):
    """Count the objects S3Storage writes."""
    saved = []
    original = S3Storage._save

    def spy(self, name, content):
        saved.append(name)
        return original(self, name, content)

    monkeypatch.setattr(S3Storage, "_save", spy)
    return saved


def test_clips_go_to_the_bucket_and_are_served_in_ranges(db, s3, clips, client, media_root,
                                                         monkeypatch):
    study = make_ranking_study(clips)
    stimulus = study.stimuli.get(source=clips[0].source, action=clips[0].action)
    assert stimulus.video == f"stimuli/{stimulus.video_hash}.mp4"
    assert keys(s3) == sorted(
        f"{PREFIX}/stimuli/{s.video_hash}.{ext}"
        for s in study.stimuli.all()
        for ext in ("mp4", "png")
    )
    assert not Path(media_root).exists() or not any(Path(media_root).rglob("*.mp4"))
    head = s3.head_object(Bucket=BUCKET, Key=f"{PREFIX}/{stimulus.video}")
    assert head["ContentType"] == "video/mp4"
    acl = s3.get_object_acl(Bucket=BUCKET, Key=f"{PREFIX}/{stimulus.video}")
    assert not any("AllUsers" in str(g["Grantee"]) for g in acl["Grants"])

    data = clips[0].video.read_bytes()
    item = shown_item(stimulus)
    url = f"/c/{item.token}.mp4"
    # Each request reads the object with one GET (a delivery's bytes are made from the
    # whole file, rendering.delivery), never through S3File's spooled local copy.
    monkeypatch.setattr(S3File, "file", property(lambda self: pytest.fail("whole download")))
    full = client.get(url)
    assert full.status_code == 200 and b"".join(full.streaming_content) == data
    assert full["Content-Type"] == "video/mp4" and full["Content-Length"] == str(len(data))
    assert full["Accept-Ranges"] == "bytes"
    for header in ("Content-Disposition", "Last-Modified", "Location"):
        assert header not in full
    assert BUCKET not in str(dict(full.items())) and "amazonaws" not in str(dict(full.items()))

    calls = []
    default_storage.connection.meta.client.meta.events.register(
        "before-call.s3", lambda model, **kw: calls.append(model.name))
    part = client.get(url, HTTP_RANGE="bytes=10-109")
    assert part.status_code == 206
    assert part["Content-Range"] == f"bytes 10-109/{len(data)}"
    assert part["Content-Length"] == "100"
    assert b"".join(part.streaming_content) == data[10:110]
    assert calls == ["HeadObject", "GetObject"]
    tail = client.get(url, HTTP_RANGE="bytes=-16")
    assert tail.status_code == 206 and b"".join(tail.streaming_content) == data[-16:]
    assert client.get(url, HTTP_RANGE=f"bytes={len(data)}-").status_code == 416

    assert client.get(url, HTTP_IF_NONE_MATCH=full["ETag"]).status_code == 304
    stale = client.get(url, HTTP_RANGE="bytes=0-9", HTTP_IF_RANGE='"other"')
    assert stale.status_code == 200 and b"".join(stale.streaming_content) == data
    assert client.head(url)["Content-Length"] == str(len(data))

    poster = client.get(f"/c/{item.token}.png")
    assert poster["Content-Type"] == "image/png"
    assert b"".join(poster.streaming_content) == clips[0].poster.read_bytes()


def test_a_clip_is_uploaded_once(db, s3, clips, uploads):
    from studyapp.stimuli.clips import register_clips

    study = make_ranking_study(clips)
    assert len(uploads) == 2 * len(clips) and len(keys(s3)) == 2 * len(clips)
    register_clips(study, clips)  # the same study again
    other = make_ranking_study(clips, slug="other-study")  # the same files, another study
    assert len(uploads) == 2 * len(clips) and len(keys(s3)) == 2 * len(clips)
    assert sorted(other.stimuli.values_list("video", flat=True)) == sorted(
        study.stimuli.values_list("video", flat=True)
    )


def first_exists_misses(monkeypatch, storage_class):
    """Make the storage's next ``exists`` answer False, as when another process stores
    the file between our ``exists`` and ``save``; return the function that undoes it."""
    real = storage_class.exists
    calls = []

    def racing(self, key):
        calls.append(key)
        return False if len(calls) == 1 else real(self, key)

    monkeypatch.setattr(storage_class, "exists", racing)
    return lambda: monkeypatch.setattr(storage_class, "exists", real)


def test_the_name_is_never_changed(db, s3, clips, uploads, monkeypatch):
    """A storage that renames (file_overwrite off) never leaves a suffixed copy."""
    from studyapp.stimuli.clips import _store

    monkeypatch.setattr(default_storage._wrapped, "file_overwrite", False)
    clip = clips[0]
    name = "0" * 64 + ".mp4"
    assert _store(clip.video, name) == f"stimuli/{name}"
    # Another process stored it between our exists() and save(): the storage picks
    # another name; that copy is removed and the content-hash name kept.
    restore = first_exists_misses(monkeypatch, S3Storage)
    assert _store(clip.video, name) == f"stimuli/{name}"
    restore()
    assert keys(s3) == [f"{PREFIX}/stimuli/{name}"]
    # A broken copy (wrong size) is replaced under the same name.
    s3.put_object(Bucket=BUCKET, Key=f"{PREFIX}/stimuli/{name}", Body=b"half")
    assert _store(clip.video, name) == f"stimuli/{name}"
    assert keys(s3) == [f"{PREFIX}/stimuli/{name}"]
    body = s3.get_object(Bucket=BUCKET, Key=f"{PREFIX}/stimuli/{name}")["Body"].read()
    assert body == clip.video.read_bytes()


def test_unknown_tokens_and_names_outside_stimuli_are_404(db, s3, clips, client):
    study = make_ranking_study(clips)
    stimulus = study.stimuli.first()
    item = shown_item(stimulus)
    assert client.get("/c/AAAAAAAAAAAAAAAAAAAAAA.mp4").status_code == 404
    tampered = item.token[:-1] + ("B" if item.token.endswith("A") else "A")
    assert client.get(f"/c/{tampered}.mp4").status_code == 404
    s3.put_object(Bucket=BUCKET, Key=f"{PREFIX}/secret.txt", Body=b"secret")
    s3.put_object(Bucket=BUCKET, Key="secret.txt", Body=b"secret")
    for name in ("secret.txt", "../secret.txt", "stimuli/../secret.txt", "/media/secret.txt",
                 "stimuli/../../secret.txt", "stimuli/", "stimuli/missing.mp4", ""):
        type(stimulus).objects.filter(pk=stimulus.pk).update(video=name)
        response = client.get(f"/c/{item.token}.mp4")
        assert response.status_code == 404, name
        assert b"secret" not in response.content


def test_fs_storage_keeps_the_name_and_leaves_no_temporary_files(db, media_root, clips,
                                                                 monkeypatch):
    from studyapp.stimuli.clips import _store

    assert isinstance(default_storage, FileSystemStorage)  # STORAGES restored after the S3 tests
    name = "1" * 64 + ".mp4"
    assert _store(clips[0].video, name) == f"stimuli/{name}"
    restore = first_exists_misses(monkeypatch, FileSystemStorage)
    assert _store(clips[0].video, name) == f"stimuli/{name}"
    restore()
    (Path(media_root) / "stimuli" / name).write_bytes(b"half")
    assert _store(clips[0].video, name) == f"stimuli/{name}"
    assert [p.name for p in (Path(media_root) / "stimuli").iterdir()] == [name]
    assert (Path(media_root) / "stimuli" / name).read_bytes() == clips[0].video.read_bytes()


def run_settings(**env):
    code = (
        "import django; django.setup(); "
        "from django.conf import settings; "
        "from django.core.files.storage import default_storage as d; "
        "print(d.__class__.__module__ + '.' + d.__class__.__name__); "
        "print(settings.STORAGES['staticfiles']['BACKEND']); "
        "print(getattr(d, 'bucket_name', '-'), getattr(d, 'location', '-'), "
        "getattr(d, 'endpoint_url', '-'), getattr(d, 'region_name', '-'))"
    )
    environ = {k: v for k, v in os.environ.items() if not k.startswith(("STUDY_S3_", "AWS_"))}
    environ.update(DJANGO_SETTINGS_MODULE="studyapp.settings", PYTHONPATH=str(ROOT), **env)
    out = subprocess.run([sys.executable, "-c", code], env=environ, cwd=ROOT, check=True,
                         capture_output=True, text=True, timeout=120)
    return out.stdout.split("\n")


def test_settings_pick_s3_when_a_bucket_is_set():
    backend, static, options, _ = run_settings(
        STUDY_S3_BUCKET="study-media", STUDY_S3_ENDPOINT_URL="http://127.0.0.1:9000",
        STUDY_S3_REGION="eu-central-1", STUDY_S3_PREFIX="/clips/",
        AWS_ACCESS_KEY_ID="key", AWS_SECRET_ACCESS_KEY="secret",
    )
    assert backend == "storages.backends.s3.S3Storage"
    assert options == "study-media clips http://127.0.0.1:9000 eu-central-1"
    backend, static_default, _, _ = run_settings()
    assert backend == "django.core.files.storage.filesystem.FileSystemStorage"
    assert static == static_default  # whitenoise (or plain in DEBUG) either way


def test_behind_nginx_each_delivery_is_an_object_of_its_own_under_a_presigned_url(
        db, s3, clips, client, settings, uploads):
    from io import StringIO
    from urllib.parse import urlsplit

    import requests

    from django.core.management import call_command

    from studyapp.stimuli import media

    settings.STUDY_ACCEL_REDIRECT = "/protected-media/"
    study = make_ranking_study(clips)
    stimulus = study.stimuli.first()
    items = [shown_item(stimulus), shown_item(stimulus)]  # one clip, two deliveries
    for item in items:
        response = client.get(f"/c/{item.token}.mp4")
        assert response.status_code == 200 and response.content == b""
        target = response["X-Accel-Redirect"]
        path, _, query = target.partition("?")
        assert path.startswith("/protected-media/s3/")
        assert path.endswith(f"{PREFIX}/deliveries/{item.token}.mp4")  # the token, nothing else
        assert "Signature=" in query
        # What nginx fetches from the bucket's host: this delivery's own bytes.
        endpoint = urlsplit(default_storage.url("x"))
        url = f"{endpoint.scheme}://{endpoint.netloc}/" + target.split("/s3/", 1)[1]
        body = requests.get(url, timeout=10).content
        stored = default_storage.open(stimulus.video).read()
        assert body == media.delivered_bytes(stored, "mp4", media.delivery_seed(item.token))
    client.get(f"/c/{items[0].token}.mp4")  # asked again: not uploaded again
    assert uploads.count(f"deliveries/{items[0].token}.mp4") == 1
    out = StringIO()
    call_command("nginx_config", "--run-dir", "/tmp", "--fetch-log", "/tmp/f.log", stdout=out)
    text = out.getvalue()
    assert "location /protected-media/s3/ {" in text and "proxy_hide_header x-amz-request-id;" in text
    assert f"proxy_set_header Host {urlsplit(default_storage.url('x')).netloc};" in text

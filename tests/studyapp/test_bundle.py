"""A study's bundle: built, answered by bots over HTTP, bundled; the analysis re-run from
the bundle gives the same numbers and build_stimuli rebuilds the same clips from it."""

import json
import zipfile
from io import StringIO

import numpy as np
import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from motion.formats import bvh, npz
from studyapp.survey.models import Study
from tests.studyapp.test_build_stimuli import small, write

pytestmark = pytest.mark.django_db(transaction=True)


def judged(slug):
    return sorted(Study.objects.get(slug=slug).stimuli.filter(role="judged").values_list(
        "source", "action", "motion_hash", "video_hash"))


def test_the_bundle_reruns_the_analysis_and_rebuilds_the_clips(tmp_path, media_root,
                                                                live_server):
    config = write(tmp_path, small(slug="bundled"))
    build = tmp_path / "build"
    call_command("build_stimuli", str(config), "--out", str(build), stdout=StringIO())
    call_command("simulate_participants", study="bundled", n=3, url=live_server.url, pace=0,
                 seed=1, stdout=StringIO())
    out = StringIO()
    call_command("bundle", study="bundled", out=str(tmp_path / "bundle.zip"),
                 manifest=str(build / "manifest.json"), stdout=out)
    assert "bundle of study bundled" in out.getvalue()
    folder = tmp_path / "unzipped"
    with zipfile.ZipFile(tmp_path / "bundle.zip") as archive:
        archive.extractall(folder)
    for name in ("config.yaml", "manifest.json", "rebuild.yaml", "responses.csv", "stimuli.csv",
                 "bundle.json", "analysis/summary.json", "motions/real.npz",
                 "motions/cond_gru.npz"):
        assert (folder / name).is_file(), name
    info = json.loads((folder / "bundle.json").read_text())
    assert info["versions"]["numpy"] == np.__version__ and info["commit"]
    assert set(info["clip_hashes"]["motion"]) >= {h for _, _, h, _ in judged("bundled")}

    # Every judged motion is in the bundle, as .npz and as BVH that reads back.
    motions = {m.content_hash(): m for name in ("real", "cond_gru")
               for m in npz.load(folder / "motions" / f"{name}.npz")}
    for source, _, motion_hash, _ in judged("bundled"):
        motion = motions[motion_hash]
        [back] = bvh.load(folder / "bvh" / source / f"{motion_hash}.bvh",
                          skeleton=motion.skeleton, scale="cm")
        np.testing.assert_allclose(back.joints, motion.joints, atol=1e-4)

    # The analysis again from the bundle: the same numbers.
    command = info["analysis"]["command"].split()[1:]
    assert command[:3] == ["analyze", "--responses", "responses.csv"]
    again = tmp_path / "again"
    arguments = [str(folder / a) if a == "responses.csv" else a for a in command[1:]]
    arguments[arguments.index("--out") + 1] = str(again)
    call_command("analyze", *arguments, stdout=StringIO())
    assert json.loads((again / "summary.json").read_text()) == json.loads(
        (folder / "analysis" / "summary.json").read_text())

    # The clips again from the bundle, without training.
    call_command("build_stimuli", str(folder / "rebuild.yaml"), "--out",
                 str(tmp_path / "rebuilt"), stdout=StringIO())
    assert [row[2:] for row in judged("bundled-rebuilt")] == [row[2:] for row in judged("bundled")]


def test_a_study_without_a_build_says_how_to_bundle_it(tmp_path, media_root):
    Study.objects.create(slug="bare", title="t")
    with pytest.raises(CommandError, match="no build manifest at .*--manifest"):
        call_command("bundle", study="bare", out=str(tmp_path / "b.zip"), stdout=StringIO())

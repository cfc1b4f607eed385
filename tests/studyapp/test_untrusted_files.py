"""Tampered motion and body-model files through every way in: nothing in them runs.

Each file's pickle would call ``os.system("touch MARKER")`` under Python's unpickler
(``tests/motion/test_safe_load.py`` shows it does). Here each goes through
``import_motions`` (every format that reads pickles, and body models), ``build_stimuli``
with a ``file:`` source, and a build job as staff start it from the admin; each is
refused with an error naming the file and the refused ``posix.system``, the marker never
appears, and good files beside a tampered one are still imported.
"""

import io
import threading

import numpy as np
import pytest
import yaml
from django.core.management import call_command
from django.core.management.base import CommandError

from motion.formats import npz
from tests.motion import untrusted_files as untrusted
from tests.motion.body_model_files import write_smpl, write_smplh
from tests.motion.test_formats_smpl import rot6d_motion
from tests.studyapp.mdm_results import write_mdm_results


def good_models(root):
    write_smpl(root)
    write_smplh(root, "male")
    return root


def good_amass(path):
    np.savez(path, poses=np.zeros((4, 156)), trans=np.zeros((4, 3)), betas=np.zeros(16),
             gender=np.array("male"), mocap_framerate=np.array(60.0))
    return path


def good_motioncritic(path):
    np.savez(path, {"prompt": list("abcd"), "motion": [rot6d_motion()[None]] * 4})
    return path


def good_actor(path, models):
    from motion.body_models import load_body_model

    _, surface = load_body_model("smpl", "neutral", models).forward(np.zeros((4, 3)),
                                                                    np.zeros((4, 69)))
    np.save(path, np.stack([np.stack([surface])]).transpose(0, 1, 3, 4, 2))
    return path


# name: (format, make(folder, marker) -> (motions file, tampered file, body models or None))
CASES = {
    "mdm results.npy": ("mdm", lambda d, m: (untrusted.mdm_results(d / "results.npy", m),) * 2
                        + (None,)),
    "mdm mesh file": ("mdm", lambda d, m: (
        untrusted.mdm_params(d / "sample00_rep00_smpl_params.npy", m),) * 2 + (None,)),
    "auto results.npy": ("auto", lambda d, m: (untrusted.mdm_results(d / "results.npy", m),) * 2
                         + (None,)),
    "auto motioncritic .npz": ("auto", lambda d, m: (
        untrusted.motioncritic_npz(d / "pair.npz", m),) * 2 + (good_models(d / "models"),)),
    "amass .npz": ("amass", lambda d, m: (untrusted.amass_npz(d / "take.npz", m),) * 2
                   + (good_models(d / "models"),)),
    "motioncritic .npz": ("motioncritic", lambda d, m: (
        untrusted.motioncritic_npz(d / "pair.npz", m),) * 2 + (good_models(d / "models"),)),
    "amass, SMPL+H model .npz": ("amass", lambda d, m: (
        good_amass(d / "take.npz"), untrusted.smplh_npz(d / "models", m), d / "models")),
    "motioncritic, SMPL model .pkl": ("motioncritic", lambda d, m: (
        good_motioncritic(d / "pair.npz"), untrusted.smpl_pkl(d / "models", m), d / "models")),
    "actor, SMPL model .pkl": ("actor", lambda d, m: (
        good_actor(d / "generation.npy", good_models(d / "good")),
        untrusted.smpl_pkl(d / "models", m), d / "models")),
    "mdm mesh, SMPL model .pkl": ("mdm", lambda d, m: (
        _good_params(d / "sample00_rep00_smpl_params.npy"), untrusted.smpl_pkl(d / "models", m),
        d / "models")),
}


def _good_params(path):
    np.save(path, {"vertices": np.zeros((6890, 3, 4)), "faces": np.zeros((10, 3), np.int64),
                   "text": "a walk", "length": 4})
    return path


def assert_refused(message: str, tampered, marker):
    assert str(tampered) in message and untrusted.SYSTEM in message, message
    assert "nothing in it was run" in message
    assert not marker.exists()


@pytest.mark.parametrize("case", CASES)
def test_import_motions_refuses_tampered_files_of_every_format(tmp_path, case):
    from motion.body_models import _cached

    _cached.cache_clear()  # a model of the same path read by an earlier test
    fmt, make = CASES[case]
    marker = tmp_path / "ran"
    motions, tampered, models = make(tmp_path, marker)
    args = [str(motions), "--format", fmt, "--out", str(tmp_path / "out.npz")]
    if models is not None:
        args += ["--body-models", str(models)]
    with pytest.raises(CommandError) as refused:
        call_command("import_motions", *args, stdout=io.StringIO())
    assert_refused(str(refused.value), tampered, marker)
    assert not (tmp_path / "out.npz").exists()


def test_good_files_beside_a_tampered_one_are_still_imported(tmp_path):
    marker = tmp_path / "ran"
    untrusted.mdm_results(tmp_path / "theirs" / "bad" / "results.npy", marker)
    write_mdm_results(tmp_path / "theirs" / "good" / "results.npy", ["a person walks"])
    err = io.StringIO()
    call_command("import_motions", str(tmp_path / "theirs"), "--format", "mdm", "--out",
                 str(tmp_path / "out.npz"), stdout=io.StringIO(), stderr=err)
    assert_refused(err.getvalue(), tmp_path / "theirs" / "bad" / "results.npy", marker)
    assert len(npz.load(tmp_path / "out.npz")) == 2  # the good file's two repetitions


def config(tmp_path, source: dict):
    raw = {"slug": "untrusted", "title": "Which looks best?", "seed": 0, "dataset": "demo",
           "actions": ["walk"], "frames": 8, "clips_per_source": 1,
           "sources": ["real", {"name": "theirs", **source}],
           "render": {"style": "stick", "size": 64}, "study": {"type": "ranking"}}
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


SOURCES = {
    "mdm results.npy": lambda d, m: ({"file": str(untrusted.mdm_results(d / "results.npy", m)),
                                      "format": "mdm", "options": {"action": "walk"}},
                                     d / "results.npy"),
    "amass, SMPL+H model .npz": lambda d, m: (
        {"file": str(good_amass(d / "take.npz")), "format": "amass",
         "options": {"body_models": str(d / "models"), "action": "walk"}},
        untrusted.smplh_npz(d / "models", m)),
}


@pytest.mark.django_db
@pytest.mark.parametrize("case", SOURCES)
def test_build_stimuli_refuses_a_tampered_file_source(tmp_path, media_root, case):
    from motion.body_models import _cached

    _cached.cache_clear()
    marker = tmp_path / "ran"
    source, tampered = SOURCES[case](tmp_path, marker)
    with pytest.raises(CommandError) as refused:
        call_command("build_stimuli", str(config(tmp_path, source)), "--out",
                     str(tmp_path / "build"), stdout=io.StringIO())
    assert "source 'theirs'" in str(refused.value)
    assert_refused(str(refused.value), tampered, marker)


@pytest.mark.django_db(transaction=True)
def test_a_staff_build_job_refuses_a_tampered_file_source(tmp_path, media_root, settings,
                                                          admin_client):
    from studyapp.survey.models import BuildJob

    settings.VAR_DIR = tmp_path / "var"
    settings.STUDY_CELERY_BROKER = ""  # the job runs in a thread of this process
    marker = tmp_path / "ran"
    source, tampered = SOURCES["mdm results.npy"](tmp_path, marker)
    page = admin_client.post("/admin/survey/buildjob/add/", {
        "config_path": str(config(tmp_path, source)), "overrides": "[]"})
    assert page.status_code == 302, page.content.decode()[:2000]
    for thread in threading.enumerate():
        if thread.name == "job-build_stimuli":
            thread.join(120)
    job = BuildJob.objects.get()
    assert job.status == BuildJob.Status.FAILED
    assert_refused(job.error, tampered, marker)

"""Stimulus sets from one config: validation, build, incremental rebuilds, imports, presets."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from motion.datasets import get_dataset
from motion.formats import npz
from generation.sampling import sample_real
from studyapp.survey.models import Study
from studyapp.stimuli.build import BuildError, build_stimuli
from studyapp.stimuli.config import ConfigError, load_config, parse

ROOT = Path(__file__).resolve().parents[2]
BVH = ROOT / "tests" / "motion" / "data" / "cmu_walk.bvh"
SMALL = ["--set", "dataset=demo"]


def small(**changes) -> dict:
    """Return a tiny demo config: 2 actions, 1 clip per source, tiny training, 64 px."""
    raw = {
        "slug": "tiny-ranking", "title": "Which looks best?", "seed": 0, "dataset": "demo",
        "actions": ["walk", "wave"], "frames": 12, "clips_per_source": 1,
        "train": {"iters": 2, "preset": "tiny"},
        "sources": ["real", "cond_gru"],
        "render": {"style": "stick", "size": 64},
        "study": {"type": "ranking"},
    }
    raw.update(changes)
    return raw


def write(tmp_path, raw, name="config.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.mark.parametrize("changes, words", [
    ({"render": {"style": "crayon"}}, ["render.style", "'crayon'", "stick2d"]),
    ({"render": {"style": "stick2d", "player": "webgl"}},
     ["render.player", "cannot draw 'stick2d'", "mesh, stick", "player video"]),
    ({"study": {"type": "poll"}}, ["study.type", "'poll'", "fake_or_real"]),
    ({"clips_per_source": 0}, ["clips_per_source", "0", "at least 1"]),
    ({"sources": ["real", "nonsense"]}, ["sources.1.method", "'nonsense'", "cond_gru"]),
    ({"sources": [{"file": "x.txt"}]}, ["sources.0.format", "'txt'", "a2m, actor, aistpp, amass, amp_poselib, auto, bvh"]),
    ({"sources": ["real", "real"]}, ["sources.1.name", "'real'", "its own name"]),
    ({"study": {"type": "ranking", "max_participants": "many"}}, ["study.max_participants", "many", "int"]),
    ({"colour": "red"}, ["'colour'", "fields are"]),
    ({"train": {"preset": "huge"}}, ["preset", "'huge'", "tiny"]),
])
def test_bad_configs_name_field_value_and_fix(tmp_path, changes, words):
    with pytest.raises(ConfigError) as error:
        parse(small(**changes), tmp_path)
    for word in words:
        assert word in str(error.value)


def test_overrides_set_any_field(tmp_path):
    path = write(tmp_path, small())
    config = load_config(path, ["dataset=h36m", "train.iters=7", "sources.1.seed=3",
                                "render.size=32", "actions=[walk]"])
    assert (config.dataset, config.size, config.actions) == ("h36m", 32, ["walk"])
    assert config.sources[1].iters == 7 and config.sources[1].seed == 3
    with pytest.raises(ConfigError, match="FIELD=VALUE"):
        load_config(path, ["train.iters"])


def snapshot(folder: Path) -> dict:
    return {p: p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}


@pytest.mark.django_db
def test_build_rebuild_and_change_one_source(tmp_path, media_root):
    config = parse(small(), tmp_path)
    folder = tmp_path / "build"
    result = build_stimuli(config, folder)
    study = Study.objects.get(slug="tiny-ranking")
    assert study.study_type == "ranking" and study.clips_per_trial == 2
    assert sorted(study.stimuli.values_list("source", "action")) == [
        ("cond_gru", "walk"), ("cond_gru", "wave"), ("real", "walk"), ("real", "wave")]
    manifest = (folder / "manifest.json").read_text()
    assert str(tmp_path) not in manifest and "checkpoint" in manifest
    assert result.rendered == 4

    before = snapshot(folder)
    again = build_stimuli(parse(small(), tmp_path), folder)
    assert (again.rendered, again.sampled) == (0, [])  # nothing sampled, rendered or written
    assert snapshot(folder) == before
    assert (folder / "manifest.json").read_text() == manifest

    changed = small(sources=["real", {"method": "cond_gru", "seed": 5}])
    third = build_stimuli(parse(changed, tmp_path), folder)
    assert third.sampled == ["cond_gru"] and third.rendered == 2 and third.removed == 2
    old = {e["source"] + e["action"]: e["video_hash"] for e in result.entries}
    new = {e["source"] + e["action"]: e["video_hash"] for e in third.entries}
    assert all(old[k] == new[k] for k in old if k.startswith("real"))
    assert all(old[k] != new[k] for k in old if k.startswith("cond_gru"))
    assert study.stimuli.count() == 4


@pytest.mark.django_db
def test_clips_render_in_worker_processes_alike_and_report_progress_per_clip(
        tmp_path, media_root, monkeypatch):
    raw = small(sources=["real", "cond_gru", {"method": "cond_gru", "seed": 3, "name": "other"}])
    steps = []
    one = build_stimuli(parse(raw, tmp_path), tmp_path / "one", cache=tmp_path / "c1",
                        progress=lambda done, total, message: steps.append(message))
    assert sum(m.startswith("rendered ") for m in steps) == one.rendered == 6
    monkeypatch.setenv("STUDY_RENDER_WORKERS", "2")
    two = build_stimuli(parse({**raw, "slug": "tiny-two"}, tmp_path), tmp_path / "two",
                        cache=tmp_path / "c2")
    assert two.rendered == 6
    hashes = lambda result: sorted(e["video_hash"] for e in result.entries)  # noqa: E731
    assert hashes(one) == hashes(two)  # the same files, whichever process drew them
    monkeypatch.setenv("STUDY_RENDER_WORKERS", "some")
    with pytest.raises(BuildError, match="STUDY_RENDER_WORKERS='some'.*whole number"):
        build_stimuli(parse({**raw, "slug": "tiny-three"}, tmp_path), tmp_path / "three",
                      cache=tmp_path / "c3")


@pytest.mark.django_db
def test_manifest_is_the_same_in_another_folder(tmp_path, media_root):
    raw = small(slug="tiny-one", sources=["real", "cond_gru"])
    build_stimuli(parse(raw, tmp_path), tmp_path / "one")
    build_stimuli(parse({**raw, "slug": "tiny-two"}, tmp_path), tmp_path / "two")
    one = (tmp_path / "one" / "manifest.json").read_text().replace("tiny-one", "tiny-two")
    assert one == (tmp_path / "two" / "manifest.json").read_text()


@pytest.mark.django_db
def test_answered_stimuli_are_never_removed(tmp_path, media_root):
    from studyapp.survey.models import Participant

    build_stimuli(parse(small(sources=["real", "cond_gru"]), tmp_path), tmp_path / "b")
    study = Study.objects.get(slug="tiny-ranking")
    participant = Participant.objects.enroll(study, {}, "")
    Participant.objects.start(participant)
    with pytest.raises(BuildError, match="never deleted"):
        build_stimuli(parse(small(sources=["real", {"method": "cond_gru", "seed": 9}]), tmp_path),
                      tmp_path / "b")
    assert study.stimuli.count() == 4


@pytest.mark.django_db
def test_each_import_format_is_a_source(tmp_path, media_root):
    demo = get_dataset("demo")
    real = sample_real(demo, ["walk", "wave"], 1, 12, seed=4)
    shifted = [m.with_joints(m.joints * np.float32(0.9), source="x", meta={}) for m in real]
    npz.save(tmp_path / "ext.npz", shifted)
    joints = np.stack([m.joints for m in shifted]) * np.float32(1.1)
    np.save(tmp_path / "a2m.npy", joints)
    np.save(tmp_path / "a2m_classes.npy", np.array([0, 3]))
    sources = [
        "real",
        {"name": "from_npz", "file": "ext.npz"},
        {"name": "from_a2m", "file": "a2m.npy", "format": "a2m",
         "options": {"classes_path": "a2m_classes.npy", "skeleton": "h36m17", "file_fps": 25.0,
                     "action_names": demo.actions()}},
        {"name": "from_bvh", "file": str(BVH), "format": "bvh",
         "options": {"skeleton": "h36m17", "action": "walk"}},
    ]
    result = build_stimuli(parse(small(sources=sources, study={"type": "pairwise"}), tmp_path),
                           tmp_path / "b")
    got = {(e["source"], e["action"]) for e in result.entries}
    assert {("from_npz", "walk"), ("from_npz", "wave"), ("from_a2m", "wave"),
            ("from_bvh", "walk")} <= got
    assert all("file" in e for e in result.entries if e["source"].startswith("from"))


@pytest.mark.django_db
def test_h36m2d_preset_builds_small(tmp_path, media_root, h36m_root):
    config = load_config(ROOT / "studies" / "sagcn_rating.yaml", [
        "clips_per_source=1", "train.iters=2", "train.preset=tiny", "actions=[Walking,Eating]",
        "render.size=64", f"data_root={h36m_root}", "frames=20", "train.seeds=[0]",
        "sources=[skeleton_gan, sa_gcn]", "metrics.train_classifier=false", "metrics.n=2",
        "metrics.repeats=2",
    ])
    result = build_stimuli(config, tmp_path / "b")
    study = result.study
    assert study.study_type == "rating_reference"
    assert study.stimuli.filter(role="reference").count() == 2
    # Catch clips: two broken versions of a clip of each source, per action (2D ones too).
    assert study.stimuli.filter(role="catch").count() == 2 * 2 * 2
    assert study.stimuli.judged().count() == 4


@pytest.mark.django_db
def test_command_dry_run_and_preset_on_demo(tmp_path, media_root):
    from django.core.management import call_command

    args = [str(ROOT / "studies" / "a2m_ranking.yaml"), "--dry-run", *SMALL,
            "--out", str(tmp_path / "b")]
    call_command("build_stimuli", *args)
    assert not (tmp_path / "b").exists()


@pytest.mark.django_db(transaction=True)
def test_build_job_records_progress_and_can_run_again(tmp_path, media_root, settings, admin_client):
    from studyapp.survey.models import BuildJob
    from studyapp.survey.tasks import execute

    settings.VAR_DIR = tmp_path / "var"
    job = BuildJob.objects.create(config_path=str(write(tmp_path, small())))
    study_id = execute("build_stimuli", {"job": job.pk})
    job.refresh_from_db()
    assert job.status == BuildJob.Status.DONE and job.study_id == study_id
    assert job.total > 0 and job.done == job.total
    stimuli = Study.objects.get(pk=study_id).stimuli.count()
    execute("build_stimuli", {"job": job.pk})  # a retry duplicates nothing
    assert Study.objects.get(pk=study_id).stimuli.count() == stimuli
    page = admin_client.get("/admin/survey/buildjob/")
    assert page.status_code == 200 and f"{job.done}/{job.total}" in page.content.decode()

    broken = BuildJob.objects.create(config_path=str(tmp_path / "missing.yaml"))
    with pytest.raises(Exception):
        execute("build_stimuli", {"job": broken.pk})
    broken.refresh_from_db()
    assert broken.status == BuildJob.Status.FAILED and "missing.yaml" in broken.error


SMALL_BUILD = ["clips_per_source=1", "train.iters=2", "train.preset=tiny", "render.size=64",
               "frames=16", "metrics.classifier_preset=tiny", "metrics.classifier_iters=5",
               "metrics.n=2", "metrics.repeats=2"]
PRESETS = {  # preset -> (study type, datasets it must build from)
    "a2m_ranking.yaml": ("ranking", ["demo", "h36m"]),
    "a2m_fake_or_real.yaml": ("fake_or_real", ["demo", "h36m"]),
    "cskeletongan_rating.yaml": ("rating_standards", ["h36m2d"]),
    "sagcn_rating.yaml": ("rating_reference", ["h36m2d"]),
    "pairwise_graded.yaml": ("pairwise_graded", ["demo", "h36m"]),
    "motionpercept_best_of_k.yaml": ("best_of_k", ["demo"]),
    "mushra_rating.yaml": ("mushra", ["demo"]),
}
ACTIONS_OF = {"demo": "[walk,wave]", "h36m": "[Walking,Eating]", "h36m2d": "[Walking,Eating]"}


@pytest.mark.slow
@pytest.mark.django_db
@pytest.mark.parametrize("preset, dataset", [
    (preset, dataset) for preset, (_, datasets) in PRESETS.items() for dataset in datasets])
def test_every_preset_builds_with_small_counts(tmp_path, media_root, preset, dataset):
    if dataset != "demo" and not (ROOT.parent / "shared" / "data" / "h36m").is_dir():
        pytest.skip("Human3.6M data not beside the project")
    overrides = [*SMALL_BUILD, f"dataset={dataset}", f"actions={ACTIONS_OF[dataset]}",
                 f"slug={preset.split('.')[0].replace('_', '-')}-{dataset}"]
    if dataset == "demo":
        overrides.append("subjects=null")  # the synthetic data has no subjects
    config = load_config(ROOT / "studies" / preset, overrides)
    result = build_stimuli(config, tmp_path / "build")
    study = result.study
    assert study.study_type == PRESETS[preset][0]
    judged = study.stimuli.judged()
    sources = {source.name for source in config.sources}
    assert set(judged.values_list("source", flat=True)) == sources
    assert judged.count() == len(sources) * 2  # one clip per source for each of 2 actions


@pytest.mark.django_db
def test_a_rebuild_keeps_crowd_settings_stored_since(tmp_path, media_root):
    crowd = {"platform": "prolific", "codes": {"completed": "AAAA1111", "no_consent": "N0",
                                               "failed_attention": "BBBB2222"}}
    build_stimuli(parse(small(study={"type": "ranking", "crowd": crowd}), tmp_path), tmp_path / "b")
    study = Study.objects.get(slug="tiny-ranking")
    stored = {**study.crowd, "prolific_study_id": "6" * 24}
    Study.objects.filter(pk=study.pk).update(crowd=stored)  # as `prolific create` does
    build_stimuli(parse(small(study={"type": "ranking", "crowd": {**crowd, "time_limit_minutes": 20}}),
                        tmp_path), tmp_path / "b")
    study.refresh_from_db()
    assert study.crowd["prolific_study_id"] == "6" * 24 and study.crowd["time_limit_minutes"] == 20

"""Building a study from real model outputs without writing Python: a file source takes
``samples:`` and ``repetitions:`` (MDM's layout), ``prompts_from: sources`` takes the prompts
every file shares (or says once, listing each source's, that they share none), motions cut
shorter than they are are reported with their lengths, ``frames: auto`` keeps the longest
length every source has, and ``--dry-run`` opens every file and says what it would build."""

import json
from pathlib import Path

import pytest
from django.core.management import call_command
from django.core.management.base import CommandError

from studyapp.stimuli.build import Build, build_stimuli
from studyapp.stimuli.config import ConfigError, load_config
from tests.studyapp.mdm_results import write_mdm_results

pytestmark = pytest.mark.django_db

ROOT = Path(__file__).resolve().parents[2]
PRESET = ROOT / "studies" / "mdm_pairwise.yaml"
PROMPTS = ["a person walks forward", "a person jumps", "someone waves"]


def config(tmp_path, *overrides, a="a.npy", b="b.npy"):
    return load_config(PRESET, [
        f"sources.0.file={tmp_path / a}", f"sources.1.file={tmp_path / b}",
        "render.size=32", "frames=20", "study.repeat_trials=0", "study.ask_demographics=false",
        "slug=from-outputs", *overrides])


def test_two_sources_from_the_repetitions_of_one_results_file(tmp_path):
    write_mdm_results(tmp_path / "one.npy", PROMPTS, repetitions=3, seed=1)
    c = config(tmp_path, "prompts_from=null", f"prompts={json.dumps(PROMPTS)}",
               "sources.0.repetitions=0", "sources.1.repetitions=1-2", a="one.npy", b="one.npy")
    assert c.sources[0].repetitions == [0] and c.sources[1].repetitions == [1, 2]
    build = Build(c, tmp_path / "build")
    first, second = (build.selected_file_motions(s) for s in c.sources)
    assert {m.meta["repetition"] for m in first} == {0} and len(first) == len(PROMPTS)
    assert {m.meta["repetition"] for m in second} == {1, 2} and len(second) == 2 * len(PROMPTS)
    study = build_stimuli(c, tmp_path / "build", cache=tmp_path / "cache").study
    judged = study.stimuli.filter(role="judged")
    assert sorted(judged.values_list("source", flat=True)) == sorted(["model_a", "model_b"] * 3)


def test_a_selection_the_file_lacks_names_what_it_has(tmp_path):
    write_mdm_results(tmp_path / "a.npy", PROMPTS, repetitions=2, seed=1)
    write_mdm_results(tmp_path / "b.npy", PROMPTS, repetitions=2, seed=2)
    c = config(tmp_path, "sources.1.repetitions=[1, 5]", "prompts_from=null",
               f"prompts={json.dumps(PROMPTS)}")
    with pytest.raises(ConfigError, match=r"sources.1.repetitions \(model_b\): file .* has "
                                          r"repetitions 0, 1; 5 is not among them"):
        Build(c, tmp_path / "build").selected_file_motions(c.sources[1])
    with pytest.raises(ConfigError, match="must be a number, a list of numbers"):
        config(tmp_path, "sources.0.samples=[-1]")
    with pytest.raises(ConfigError, match="samples: not a field of a method source|not a field"):
        config(tmp_path, "sources.0={method: cond_gru, samples: [0]}")


def test_samples_of_a_file_that_does_not_number_them_are_refused(tmp_path):
    from motion.formats import npz
    from motion.formats.mdm import load as load_mdm

    write_mdm_results(tmp_path / "a.npy", PROMPTS, repetitions=1, seed=1)
    motions = [m.with_joints(m.joints, meta={}) for m in load_mdm(tmp_path / "a.npy")]
    npz.save(tmp_path / "plain.npz", motions)
    c = config(tmp_path, "sources.1.format=npz", "sources.1.samples=0", "prompts_from=null",
               f"prompts={json.dumps(PROMPTS)}", b="plain.npz")
    with pytest.raises(ConfigError, match=r"does not number its motions' samples \(MDM's "
                                          r"results.npy does\); drop samples"):
        Build(c, tmp_path / "build").selected_file_motions(c.sources[1])


def test_prompts_from_sources_takes_the_prompts_every_file_shares(tmp_path):
    write_mdm_results(tmp_path / "a.npy", PROMPTS, repetitions=1, seed=1)
    write_mdm_results(tmp_path / "b.npy", ["Someone waves.", "a person sits", PROMPTS[0]],
                      repetitions=1, seed=2)
    c = config(tmp_path, "prompts_from=sources")
    assert Build(c, tmp_path / "build").config.prompts == [PROMPTS[0], PROMPTS[2]]


def test_sources_that_share_no_prompt_are_told_once_with_each_sources_prompts(tmp_path):
    write_mdm_results(tmp_path / "a.npy", PROMPTS, repetitions=1, seed=1)
    write_mdm_results(tmp_path / "b.npy", ["a person sits", "a person kicks"], repetitions=1,
                      seed=2)
    c = config(tmp_path, "prompts_from=sources")
    with pytest.raises(ConfigError) as caught:
        Build(c, tmp_path / "build")
    message = str(caught.value)
    assert "the sources share no prompt" in message
    assert "model_a has 3 ('a person walks forward'" in message
    assert "model_b has 2 ('a person sits', 'a person kicks')" in message
    with pytest.raises(ConfigError, match="drop actions"):
        config(tmp_path, "prompts_from=sources", "actions=[walk]")


def test_motions_cut_shorter_are_reported_and_frames_auto_keeps_the_shortest(tmp_path):
    write_mdm_results(tmp_path / "a.npy", PROMPTS, repetitions=1, frames=50, seed=1,
                      lengths=[50, 44, 36])
    write_mdm_results(tmp_path / "b.npy", PROMPTS, repetitions=1, frames=50, seed=2,
                      lengths=[50, 50, 48])
    fixed = build_stimuli(config(tmp_path, "prompts_from=sources"), tmp_path / "fixed",
                          cache=tmp_path / "cache")
    assert fixed.warnings == [
        "model_a: 3 of its 3 motions were cut to 20 frames (1.0 s) from 36-50; set frames: "
        "auto for the longest length every source has, or frames: N",
        "model_b: 3 of its 3 motions were cut to 20 frames (1.0 s) from 48-50; set frames: "
        "auto for the longest length every source has, or frames: N"]
    auto = config(tmp_path, "frames=auto", "slug=from-outputs-auto", "prompts_from=sources")
    assert auto.frames is None and auto.frames_auto
    built = build_stimuli(auto, tmp_path / "auto", cache=tmp_path / "cache")
    assert Build(auto, tmp_path / "auto").clip_frames() == 36  # model_a's shortest
    assert {s.duration for s in built.study.stimuli.filter(role="judged")} == {36 / 20}
    assert len(built.warnings) == 2 and "cut to 36 frames" in built.warnings[0]


def test_a_dry_run_opens_every_file_and_says_what_it_would_take(tmp_path, capsys):
    write_mdm_results(tmp_path / "a.npy", PROMPTS, repetitions=2, frames=50, seed=1)
    write_mdm_results(tmp_path / "b.npy", PROMPTS, repetitions=1, frames=50, seed=2)
    args = ["build_stimuli", str(PRESET), "--dry-run", "--out", str(tmp_path / "out"),
            "--set", f"sources.0.file={tmp_path / 'a.npy'}",
            "--set", f"sources.1.file={tmp_path / 'b.npy'}", "--set", "frames=20",
            "--set", "prompts_from=sources"]
    call_command(*args)
    out = capsys.readouterr().out
    assert (f"model_a: file {tmp_path / 'a.npy'} (mdm): 6 motions, 3 prompts; 6 of them for "
            f"this study's prompts, 50-50 frames; 6 would be cut to 20 frames (frames: auto "
            f"would take 50, the shortest)") in out
    assert not (tmp_path / "out" / "manifest.json").exists()
    (tmp_path / "b.npy").write_bytes(b"not a results file")
    with pytest.raises(CommandError, match=r"sources: file .*b.npy.* of source 'model_b'"):
        call_command(*args)

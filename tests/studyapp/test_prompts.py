"""Text prompts as conditions: config checks, matching motions to prompts, the build."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from motion.formats import npz
from motion.motion import Motion
from studyapp.stimuli.build import build_stimuli, motions_for_prompts
from studyapp.stimuli.config import ConfigError, load_config, parse, prompt_key
from tests.studyapp.mdm_results import moving_body, write_mdm_results

ROOT = Path(__file__).resolve().parents[2]
PROMPTS = ["a person walks forward", "a person jumps up", "someone waves", "a man sits down"]


def config(**changes) -> dict:
    raw = {
        "slug": "prompt-pairs", "title": "Which fits the text better?", "seed": 0,
        "dataset": "humanml3d", "prompts": list(PROMPTS), "frames": 20, "clips_per_source": 1,
        "sources": [{"name": "model_a", "file": "a/results.npy", "format": "mdm"},
                    {"name": "model_b", "file": "b/results.npy", "format": "mdm"}],
        "render": {"style": "stick", "size": 64},
        "study": {"type": "pairwise", "practice": False, "catch_trials": 1},
    }
    raw.update(changes)
    return raw


@pytest.mark.parametrize("changes, words", [
    ({"actions": ["walk"]}, ["actions and prompts", "drop actions"]),
    ({"prompts_from": "p.txt"}, ["prompts and prompts_from", "give one of them"]),
    ({"prompts": []}, ["prompts", "non-empty list"]),
    ({"prompts": ["a person jumps", 3]}, ["prompts", "prompt 2", "non-empty text"]),
    ({"prompts": ["a person jumps.", "A  person  jumps"]}, ["prompts", "'A person jumps'",
                                                            "same prompt as", "once"]),
    ({"prompts": ["x" * 501]}, ["prompts", "501 characters", "at most 500"]),
    ({"prompts_from": "missing.txt", "prompts": None}, ["prompts_from", "'missing.txt'",
                                                        "fix the path"]),
    ({"sources": [{"file": "a/results.npy", "format": "mdm"}, "a2m"]},
     ["sources.1", "'a2m'", "action-conditioned", "format: mdm"]),
    ({"study": {"type": "pairwise", "practice": True}}, ["study.practice", "practice: false"]),
    ({"study": {"type": "rating_reference"}}, ["study.type", "rating_reference", "reference",
                                               "pairwise"]),
])
def test_bad_prompt_configs_name_the_key_and_the_fix(tmp_path, changes, words):
    with pytest.raises(ConfigError) as error:
        parse(config(**changes), tmp_path)
    for word in words:
        assert word in str(error.value)


def test_prompts_from_a_text_file_or_an_interchange_npz(tmp_path):
    (tmp_path / "prompts.txt").write_text(
        "# a comment\n\na person walks forward#a/DET person/NOUN#0.0#0.0\nsomeone waves\n"
        "Someone waves.\n")
    raw = config(prompts=None, prompts_from="prompts.txt")
    assert parse(raw, tmp_path).prompts == ["a person walks forward", "someone waves"]
    motions = [Motion(moving_body(10, i), "smpl22", 20.0, "unknown", "mdm", text=text)
               for i, text in enumerate(["a man sits down", "", "a man sits down", "someone waves"])]
    npz.save(tmp_path / "mine.npz", motions)
    raw = config(prompts=None, prompts_from="mine.npz")
    assert parse(raw, tmp_path).prompts == ["a man sits down", "someone waves"]
    np.save(tmp_path / "results.npy", {"motion": np.zeros((1, 22, 3, 4))})
    with pytest.raises(ConfigError, match="prompts_from: 'results.npy' is not a text file.*"
                                          "import_motions results.npy"):
        parse(config(prompts=None, prompts_from="results.npy"), tmp_path)
    (tmp_path / "prompts.csv").write_text("file,text\nsample00.npy,a man sits down\n"
                                          "sample01.npy,someone waves\n")
    raw = config(prompts=None, prompts_from="prompts.csv")
    assert parse(raw, tmp_path).prompts == ["a man sits down", "someone waves"]
    (tmp_path / "bad.csv").write_text("file,words\nx,y\n")
    with pytest.raises(ConfigError, match="prompts_from: 'bad.csv'.*expected a text"):
        parse(config(prompts=None, prompts_from="bad.csv"), tmp_path)
    (tmp_path / "empty.txt").write_text("# nothing\n")
    with pytest.raises(ConfigError, match="prompts_from: 'empty.txt' holds no prompt"):
        parse(config(prompts=None, prompts_from="empty.txt"), tmp_path)


def motion(text, frames=30, seed=0):
    return Motion(moving_body(frames, seed), "smpl22", 20.0, "unknown", "mdm", text=text)


def test_motions_match_prompts_by_text_ignoring_case_spacing_and_full_stop():
    motions = [motion("A person  walks forward.", seed=1), motion("someone waves", seed=2),
               motion("a person walks forward", seed=3)]
    out = motions_for_prompts(["a person walks forward", "Someone waves"], motions, 2 - 1, 20,
                              "sources.0 (model_a)")
    assert [m.text for m in out] == ["a person walks forward", "Someone waves"]
    assert [m.meta["caption"] for m in out] == ["A person  walks forward.", "someone waves"]
    assert [m.action for m in out] == ["a person walks forward", "Someone waves"]
    assert all(m.frames == 20 for m in out)
    two = motions_for_prompts(["a person walks forward"], motions, 2, 20, "sources.0 (model_a)")
    assert len(two) == 2


def test_a_prompt_a_source_lacks_is_named_with_the_source_and_close_matches():
    motions = [motion("a person walks forward"), motion("a person walks backward"),
               motion("a man sits down")]
    with pytest.raises(ConfigError) as error:
        motions_for_prompts(["a person walks forwards slowly"], motions, 1, 20,
                            "sources.1 (model_b)")
    message = str(error.value)
    for word in ("prompts:", "sources.1 (model_b)", "'a person walks forwards slowly'",
                 "close matches", "'a person walks forward'", "'a person walks backward'",
                 "Fix the prompt"):
        assert word in message
    assert "a man sits down" not in message
    with pytest.raises(ConfigError, match="no motion for prompt 'xyzzy'; it has 3 other prompts"):
        motions_for_prompts(["xyzzy"], motions, 1, 20, "sources.1 (model_b)")


def test_too_few_or_too_short_motions_say_what_to_change():
    motions = [motion("a man sits down", frames=12)]
    with pytest.raises(ConfigError, match=r"0 motion\(s\) of at least 20 frames for prompt "
                                          r"'a man sits down'.*set frames to 12 or less"):
        motions_for_prompts(["a man sits down"], motions, 1, 20, "sources.0 (model_a)")
    with pytest.raises(ConfigError, match="lower clips_per_source"):
        motions_for_prompts(["a man sits down"], motions, 2, 10, "sources.0 (model_a)")


def test_a_long_prompt_keys_its_clips_by_its_start_and_a_hash():
    long = "a person " + "walks and then " * 20 + "stops"
    key = prompt_key(long)
    assert len(key) <= 100 and key.startswith("a person walks") and key != prompt_key(long + "!")
    assert prompt_key("  a  person jumps ") == "a person jumps"


@pytest.mark.django_db
def test_a_prompt_study_builds_one_condition_per_prompt(tmp_path, media_root):
    write_mdm_results(tmp_path / "a" / "results.npy", PROMPTS, repetitions=2, seed=1)
    variants = [p.capitalize() + "." for p in PROMPTS][::-1]  # other order, case and stop
    write_mdm_results(tmp_path / "b" / "results.npy", variants, repetitions=1, seed=2)
    result = build_stimuli(parse(config(), tmp_path), tmp_path / "build")
    study = result.study
    judged = study.stimuli.judged()
    assert judged.count() == 2 * len(PROMPTS)
    assert sorted(set(judged.values_list("prompt", flat=True))) == sorted(PROMPTS)
    for stimulus in judged:
        assert stimulus.action == stimulus.prompt  # the trial's condition is its prompt
    catch = study.stimuli.filter(role="catch")  # two broken clips of each source's, per prompt
    assert sorted(catch.values_list("prompt", flat=True)) == sorted(PROMPTS * 4)
    manifest = json.loads(result.manifest.read_text())
    assert {e["prompt"] for e in manifest["clips"]} == set(PROMPTS)
    # The default instructions speak of a text, not of a named action.
    assert "a person walks forward and waves" in study.instructions
    assert "matches the text better" in study.instructions
    assert "action" not in study.instructions

    # A prompt only one source has: the error names it, the other source and close matches.
    raw = config(prompts=[*PROMPTS, "a person jumps up high"], slug="other")
    write_mdm_results(tmp_path / "a" / "results.npy", [*PROMPTS, "a person jumps up high"],
                      repetitions=1, seed=1)
    with pytest.raises(ConfigError) as error:
        build_stimuli(parse(raw, tmp_path), tmp_path / "build2")
    assert "sources.1 (model_b) has no motion for prompt 'a person jumps up high'" in str(error.value)
    assert "'A person jumps up.'" in str(error.value)


def test_the_mdm_pairwise_preset_reads(tmp_path):
    config = load_config(ROOT / "studies" / "mdm_pairwise.yaml")
    assert config.study_type == "pairwise" and len(config.prompts) == 4
    assert [s.format for s in config.sources] == ["mdm", "mdm"]
    assert yaml.safe_load((ROOT / "studies" / "mdm_pairwise.yaml").read_text())["study"][
        "practice"] is False


def write_humanml3d(root, captions, frames=40):
    """Write a HumanML3D-layout folder: one clip per caption, new_joints/ and texts/."""
    (root / "new_joints").mkdir(parents=True)
    (root / "texts").mkdir()
    for i, caption in enumerate(captions):
        np.save(root / "new_joints" / f"{i:06d}.npy", moving_body(frames, 100 + i))
        (root / "texts" / f"{i:06d}.txt").write_text(f"{caption}#a/DET person/NOUN#0.0#0.0\n")


@pytest.mark.django_db
def test_real_clips_of_a_prompt_come_from_captions_and_show_the_configs_prompt(tmp_path,
                                                                               media_root):
    write_humanml3d(tmp_path / "hml", ["A person walks forward.", "someone waves",
                                       "a person walks forward", "a man sits down"])
    write_mdm_results(tmp_path / "a" / "results.npy", PROMPTS, repetitions=1, seed=1)
    raw = config(prompts=["a person walks forward", "someone waves"], data_root="hml",
                 sources=["real", {"name": "model_a", "file": "a/results.npy", "format": "mdm"}],
                 clips_per_source=1)
    raw["data_root"] = str(tmp_path / "hml")
    study = build_stimuli(parse(raw, tmp_path), tmp_path / "build").study
    real = study.stimuli.judged().filter(source="real")
    assert sorted(real.values_list("prompt", flat=True)) == ["a person walks forward",
                                                             "someone waves"]
    # Real clips set the framing: another model_a re-renders only model_a's clips.
    raw["study"] = {"type": "pairwise", "practice": False, "catch_trials": 0}
    build_stimuli(parse(raw, tmp_path), tmp_path / "build")
    write_mdm_results(tmp_path / "a" / "results.npy", PROMPTS, repetitions=1, seed=9)
    again = build_stimuli(parse(raw, tmp_path), tmp_path / "build")
    assert again.sampled == ["model_a"] and again.rendered == 2
    raw["prompts"] = ["a person walks forwards"]
    with pytest.raises(ConfigError) as error:
        build_stimuli(parse({**raw, "slug": "other"}, tmp_path), tmp_path / "build2")
    assert ("sources.0 (real) has no motion for prompt 'a person walks forwards'; close "
            "matches: 'A person walks forward.'") in str(error.value)


@pytest.mark.django_db
def test_real_clips_for_prompts_need_a_dataset_with_captions(tmp_path, media_root):
    write_mdm_results(tmp_path / "a" / "results.npy", PROMPTS, repetitions=1, seed=1)
    raw = config(dataset="demo", sources=["real", {"name": "model_a", "file": "a/results.npy",
                                                   "format": "mdm"}])
    with pytest.raises(ConfigError, match=r"sources.0 \(real\): real clips for prompts come "
                                          r"from a dataset with captions.*humanml3d, kit_ml.*"
                                          r"dataset 'demo' has none.*--format humanml3d"):
        build_stimuli(parse(raw, tmp_path), tmp_path / "build")


@pytest.mark.django_db
def test_sources_of_different_skeletons_are_refused_as_they_would_tell(tmp_path, media_root):
    write_mdm_results(tmp_path / "a" / "results.npy", PROMPTS, repetitions=1, seed=1)
    data = write_mdm_results(tmp_path / "b" / "results.npy", PROMPTS, repetitions=1, seed=2)
    data["motion"] = data["motion"][:, :21] * 1000  # KIT-ML's 21 joints in millimetres
    np.save(tmp_path / "b" / "results.npy", data)
    with pytest.raises(ConfigError, match="'model_b' has skeleton kit21 but 'model_a' has "
                                          "smpl22; the figure would tell"):
        build_stimuli(parse(config(), tmp_path), tmp_path / "build")


@pytest.mark.parametrize("study_type", ["pairwise", "ranking", "fake_or_real"])
def test_default_instructions_of_every_prompt_type_speak_of_a_text(study_type):
    from studyapp.survey.models import Study
    from studyapp.survey.study_types import get_study_type

    kind = get_study_type(study_type)
    draft = Study(study_type=study_type, options={}, clips_per_trial=kind.default_clips_per_trial)
    text = kind.prompt_instructions(draft)
    assert "for example \"a person walks forward and waves\"" in text
    assert "action" not in text


@pytest.mark.parametrize("study_type", ["pairwise", "ranking", "fake_or_real"])
def test_the_analysis_reports_per_prompt_where_it_reports_per_action(study_type):
    from analysis.simulate import simulate
    from analysis.study import AnalysisConfig, analyse

    table = simulate(study_type, {"real": 1.0, "model_a": 0.0, "model_b": -0.5},
                     participants=12, trials=4, actions=("walk", "wave"), seed=3)
    texts = {"walk": "a person walks forward", "wave": "someone waves & <smiles>"}
    table["prompt"] = table["action"].map(texts)
    result = analyse(table, AnalysisConfig(bootstrap=20))
    names = [t.name for t in result.tables]
    assert not any("action" in name for name in names)
    by_prompt = next(t for t in result.tables if t.name == "by_prompt")
    assert "per prompt" in by_prompt.title
    frame = by_prompt.frame.reset_index()
    assert sorted(frame["prompt"].unique()) == sorted(texts.values())
    assert result.counts["prompts"] == 2 and "2 text prompts" in result.methods()
    plain = analyse(table.drop(columns="prompt"), AnalysisConfig(bootstrap=20))
    assert "by_action" in [t.name for t in plain.tables] and "prompts" not in plain.counts


@pytest.mark.django_db
@pytest.mark.parametrize("study_type, fields", [
    ("ranking", {"clips_per_trial": 2}), ("fake_or_real", {"clips_per_trial": 1})])
def test_ranking_and_fake_or_real_studies_of_prompts_build_and_can_be_taken(
        tmp_path, media_root, make_bot, study_type, fields):
    from django.utils.html import escape

    prompts = ["a person jumps <twice> & lands", "someone waves"]
    write_humanml3d(tmp_path / "hml", ["A person jumps <twice> & lands.", "someone waves"])
    write_mdm_results(tmp_path / "a" / "results.npy", prompts, repetitions=1, seed=1)
    raw = config(prompts=prompts, slug=f"prompts-{study_type.replace('_', '-')}",
                 data_root=str(tmp_path / "hml"),
                 sources=["real", {"name": "model_a", "file": "a/results.npy", "format": "mdm"}],
                 study={"type": study_type, "practice": False, "catch_trials": 1, **fields})
    study = build_stimuli(parse(raw, tmp_path), tmp_path / "build").study
    study.status = "open"
    study.save()
    bot = make_bot(study)
    bot.join()
    shown = []
    while (trial := bot.participant().current_trial()) is not None:
        page = bot.trial_page().content.decode()
        assert escape(trial.prompt) in page and "<twice>" not in page
        assert "model_a" not in page
        shown.append(trial.prompt)
        bot.answer(bot.answer_data(trial), follow=True)
    assert set(shown) == set(prompts)

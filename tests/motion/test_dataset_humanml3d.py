"""The humanml3d dataset: real clips with captions, in HumanML3D's layout."""

import numpy as np
import pytest

from motion.datasets import DatasetError, get_dataset
from tests.motion.test_formats_text_to_motion import walking


@pytest.fixture
def root(tmp_path):
    (tmp_path / "new_joints").mkdir()
    (tmp_path / "texts").mkdir()
    np.save(tmp_path / "new_joints" / "000001.npy", walking(80, seed=1))
    np.save(tmp_path / "new_joints" / "000002.npy", walking(70, seed=2))
    (tmp_path / "texts" / "000001.txt").write_text(
        "A person walks forward.#a/DET#0.0#0.0\nsomeone walks#someone/PRON#0.0#0.0\n"
        "a person turns around#a/DET#1.0#3.0\n")
    (tmp_path / "texts" / "000002.txt").write_text("a person   walks forward#a/DET#0.0#0.0\n")
    return tmp_path


def test_takes_carry_captions_and_spans_become_their_own_takes(root):
    dataset = get_dataset("humanml3d", root)
    takes = dataset.load_takes().motions
    assert [t.meta["take"] for t in takes] == ["000001", "000001@20", "000002"]
    assert takes[0].text == "A person walks forward." and takes[1].frames == 40
    assert takes[1].text == "a person turns around" and takes[0].skeleton == "smpl22"
    assert dataset.actions() == ["unknown"]
    clips = dataset.clips(frames=30)
    assert clips and all(c.text for c in clips)


def test_real_clips_for_a_prompt(root):
    dataset = get_dataset("humanml3d", root)
    found = dataset.takes_for("a person walks forward")
    assert [t.meta["take"] for t in found] == ["000001", "000002"]
    assert found[1].text == "a person   walks forward"
    assert "someone walks" in dataset.prompts() and dataset.takes_for("nobody") == []


def test_missing_layout_says_what_is_expected(tmp_path):
    with pytest.raises(DatasetError, match="has no new_joints/ folder.*STUDY_HUMANML3D_ROOT"):
        get_dataset("humanml3d", tmp_path).load_takes()

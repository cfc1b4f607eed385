"""Every registered format: a detector, an example file in its codebase's layout that auto
recognises as that format and that reads into plausible motions, and a malformed file
whose error names the file and what is wrong."""

import numpy as np
import pytest

from motion import ops
from motion.formats import FormatError, get_format, list_formats, load_motions
from motion.formats.auto import detect
from motion.formats.probe import Probe
from motion.skeletons import get_skeleton
from tests.motion.body_model_files import write_smpl, write_smplx
from tests.motion.format_examples import EXAMPLES, MALFORMED, MALFORMED_OPTIONS

FORMATS = [name for name in list_formats() if name != "auto"]
BODY_MODEL_OPTION = "body_models"


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    root = tmp_path_factory.mktemp("body_models")
    write_smpl(root)
    write_smplx(root)
    return root


def options_for(name, options, models):
    from motion.formats import format_options

    if BODY_MODEL_OPTION in format_options(name):
        options = {**options, BODY_MODEL_OPTION: models}
    return options


def test_every_format_has_a_detector_an_example_and_a_malformed_file():
    assert set(FORMATS) == set(EXAMPLES) == set(MALFORMED)
    assert all(callable(getattr(get_format(name), "detect", None)) for name in FORMATS)


@pytest.mark.parametrize("name", FORMATS)
def test_the_example_is_detected_as_its_format_and_reads(tmp_path, name, models):
    path, options = EXAMPLES[name](tmp_path)
    fmt, why = detect(path, options)
    assert fmt == name, why
    others = [other for other in FORMATS
              if other != name and get_format(other).detect(Probe(path, options))]
    assert not others, f"{path.name} is also recognised by {others}"
    motions = load_motions(path, "auto", **options_for(name, options, models))
    assert motions and all(np.isfinite(m.joints).all() for m in motions)
    for motion in motions:
        skeleton = get_skeleton(motion.skeleton)
        assert motion.joints.shape[1:] == (skeleton.n_joints, skeleton.dims)
        # Upright, on the floor, of a person's height, in the renderer's frame (z up, m).
        up = ops.canonical(motion).joints[..., 2]
        height = np.median(up.max(axis=1) - up.min(axis=1))
        assert 1.0 < height < 2.3, f"{name}: {height:.2f} m tall"
        assert abs(np.median(up.min(axis=1))) < 0.1, f"{name}: feet at {up.min():.2f} m"


@pytest.mark.parametrize("name", FORMATS)
def test_a_malformed_file_says_which_file_and_what_is_wrong(tmp_path, name, models):
    write, message = MALFORMED[name]
    path = write(tmp_path)
    options = MALFORMED_OPTIONS.get(name, lambda folder: {})(tmp_path)
    with pytest.raises(FormatError, match=message) as error:
        load_motions(path, name, **options_for(name, options, models))
    assert path.name in str(error.value) or str(path) in str(error.value)

"""The demo has a study of every registered type: a type without a YAML file of its own is
built from ``_common.yaml`` with its key, slug and label, so a new type needs no demo file."""

import shutil

from studyapp.stimuli.config import load_config
from studyapp.stimuli.management.commands.demo import DEMO_CONFIGS, demo_configs
from studyapp.survey.study_types import get_study_type, list_study_types


def test_every_type_without_a_file_is_built_from_the_common_config(tmp_path):
    shutil.copy(DEMO_CONFIGS / "_common.yaml", tmp_path / "_common.yaml")
    first = list_study_types()[0]
    (tmp_path / "mine.yaml").write_text(
        f"extends: _common.yaml\nslug: mine\ntitle: Mine\nstudy:\n  type: {first}\n")
    configs = [load_config(path, fixed) for path, fixed in demo_configs(tmp_path)]
    assert sorted(c.study_type for c in configs) == list_study_types()
    assert [c.slug for c in configs if c.study_type == first] == ["mine"]
    for config in configs[1:]:
        assert config.slug == "demo-" + config.study_type.replace("_", "-")
        assert config.title == get_study_type(config.study_type).label


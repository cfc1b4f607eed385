"""Closed plug-ins: a study type's key is named only in the type's own files.

A study type is its module and template in ``studyapp/survey/study_types/`` and its
analysis module in ``analysis/``; its tests are its own test files (``test_<key>.py``,
``test_browser_<key>.py``, ``test_<analysis module>.py``). Anything else that needs to
know about a type asks the registry and the plug-in's hooks. Migrations are frozen
history, and ``studies/`` and ``docs/`` are data and prose, so none of them is read.
"""

import inspect
import io
import re
import tokenize
from pathlib import Path

import pytest

from analysis.registry import get_analysis, list_analyses
from studyapp.survey.study_types import FOLDER, StudyType, get_study_type, list_study_types
from tests.conftest import ROOT

SKIPPED = {".venv", ".git", "studies", "docs", "migrations", "node_modules", "__pycache__"}
SUFFIXES = {".py", ".html", ".js"}

# Files that use one existing type as the example study of a shared feature (the flow,
# the crowd, the build, the export, ...) and the keys they may name. The list can only
# shrink: a listed file that no longer names a key fails, as does any file not listed.
EXAMPLES = {
    "benchmarks/loadtest.py": {"ranking"},
    "studyapp/survey/models/study.py": {"ranking"},  # Study.study_type's default, as migrated
    "tests/analysis/test_bad_input.py": {"fake_or_real", "pairwise", "ranking", "rating_standards"},
    "tests/analysis/test_correlate.py": {"ranking"},
    "tests/analysis/test_crossed.py": {"pairwise", "rating_standards"},
    "tests/analysis/test_exclusions.py": {"fake_or_real", "ranking"},
    # the mixed models are fitted where a type's answers suit one (scores, yes/no)
    "tests/analysis/test_mixed.py": {"fake_or_real", "mushra", "rating_standards"},
    "tests/analysis/test_pairwise_graded.py": {"pairwise"},
    "tests/analysis/test_participant_intervals.py": {"fake_or_real", "rating_standards"},
    "tests/analysis/test_plan.py": {"rating_standards"},
    "tests/studyapp/conftest.py": {"ranking"},
    "tests/studyapp/test_analyze_command.py": {"fake_or_real", "ranking"},
    "tests/studyapp/test_analyze_escaping.py": {"ranking"},
    "tests/studyapp/test_audit.py": {"ranking"},
    "tests/studyapp/test_browser_checks.py": {"mushra", "pairwise"},
    "tests/studyapp/test_browser_criteria.py": {"ranking", "rating_reference"},
    "tests/studyapp/test_browser_types.py": {"best_of_k", "fake_or_real", "mushra", "pairwise",
                                             "rating_reference", "rating_standards"},
    "tests/studyapp/test_build_stimuli.py": {"best_of_k", "fake_or_real", "mushra", "pairwise",
                                             "pairwise_graded", "ranking", "rating_reference",
                                             "rating_standards"},
    "tests/studyapp/test_commands.py": {"fake_or_real", "pairwise", "ranking", "rating_reference"},
    "tests/studyapp/test_correlate_command.py": {"ranking"},
    "tests/studyapp/test_criteria.py": {"fake_or_real", "pairwise", "ranking", "rating_reference",
                                        "rating_standards"},
    "tests/studyapp/test_crowd.py": {"fake_or_real", "ranking"},
    "tests/studyapp/test_crowd_integrity.py": {"ranking"},
    "tests/studyapp/test_delivery_serving.py": {"ranking"},
    "tests/studyapp/test_demo_debug.py": {"ranking"},
    "tests/studyapp/test_end_to_end.py": {"fake_or_real", "pairwise", "ranking", "rating_reference",
                                          "rating_standards"},
    "tests/studyapp/test_flow.py": {"ranking"},
    "tests/studyapp/test_instructed_checks.py": {"pairwise"},
    "tests/studyapp/test_migrations.py": {"pairwise", "rating_reference"},
    "tests/studyapp/test_plan_command.py": {"pairwise", "rating_standards"},
    "tests/studyapp/test_plan_page.py": {"pairwise"},
    "tests/studyapp/test_prolific_command.py": {"ranking"},
    "tests/studyapp/test_prolific_end_to_end.py": {"ranking"},
    "tests/studyapp/test_prompts.py": {"fake_or_real", "pairwise", "ranking", "rating_reference"},
    "tests/studyapp/test_stimulus_sources.py": {"ranking"},
    "tests/studyapp/test_study_types.py": {"best_of_k", "fake_or_real", "mushra", "pairwise",
                                           "pairwise_graded", "ranking", "rating_reference",
                                           "rating_standards"},
    "tests/studyapp/test_tasks.py": {"ranking"},
    "tests/studyapp/test_untrusted_files.py": {"ranking"},
}


def project_files():
    for path in sorted(ROOT.rglob("*")):
        parts = set(path.relative_to(ROOT).parts)
        if (path.suffix in SUFFIXES and path.is_file() and not parts & SKIPPED
                and path != Path(__file__).resolve()):  # this file lists the examples
            yield path


def named_keys(path: Path, keys) -> set[str]:
    """Return the keys of ``keys`` written as a whole string literal in ``path``."""
    text = path.read_text(errors="replace")
    if path.suffix != ".py":
        return {k for k in keys if re.search(rf"""["']{re.escape(k)}["']""", text)}
    found = set()
    for token in tokenize.generate_tokens(io.StringIO(text).readline):
        if token.type == tokenize.STRING:
            body = re.sub(r"^[rbuRBU]*", "", token.string).strip("'\"")
            if body in keys:
                found.add(body)
    return found


def own_files(key: str) -> set[Path]:
    """Return the files that belong to study type ``key``."""
    study_type = get_study_type(key)
    module = Path(inspect.getfile(type(study_type)))
    template = FOLDER / study_type.template_name()
    analysis = Path(inspect.getfile(type(get_analysis(key))))
    files = {FOLDER / f"{key}.py", module, template, template.with_suffix(".py"), analysis}
    stems = {key, analysis.stem}
    for path in (ROOT / "tests").rglob("test_*.py"):
        name = path.stem[len("test_"):]
        if name in stems or name.endswith(f"_{key}"):
            files.add(path)
    return {f.resolve() for f in files}


def test_every_registered_type_has_its_analysis_and_every_analysis_its_type():
    assert list_study_types() == list_analyses()


def test_no_file_outside_a_type_names_its_key():
    keys = set(list_study_types())
    owners = {key: own_files(key) for key in keys}
    wrong, stale = [], []
    for path in project_files():
        relative = path.relative_to(ROOT).as_posix()
        named = {k for k in named_keys(path, keys) if path.resolve() not in owners[k]}
        allowed = EXAMPLES.get(relative, set())
        if named - allowed:
            wrong.append(f"{relative}: {', '.join(sorted(named - allowed))}")
        if allowed - named:
            stale.append(f"{relative}: {', '.join(sorted(allowed - named))}")
    assert not wrong, ("these files name a study type's key outside its own files; ask the "
                       "registry or a hook of the plug-in instead:\n" + "\n".join(wrong))
    gone = sorted(name for name in EXAMPLES if not (ROOT / name).exists())
    assert not stale and not gone, ("these files no longer name what EXAMPLES allows them, "
                                    "or are gone; shrink the list:\n" + "\n".join(stale + gone))


@pytest.mark.parametrize("key", list_study_types())
def test_a_type_brings_its_hooks(key):
    """What shared code asks of a type is there: answers for bots and tests (a valid post,
    a catch trial spotted and missed), the simulation."""
    from analysis.simulate import can_simulate

    kind = type(get_study_type(key))
    for hook in ("bot_answer", "answer_fields", "catch_answers", "obey", "obeyed"):
        assert getattr(kind, hook) is not getattr(StudyType, hook), f"{key} lacks {hook}"
    analysis = get_analysis(key)
    assert analysis.answer and can_simulate(analysis)

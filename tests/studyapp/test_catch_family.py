"""Catch clips come as a family: per action, broken versions of a clip of every source
(never a judged one), of different kinds; each new participant gets the least used."""

from collections import Counter
from pathlib import Path

import pytest

from studyapp.survey.models import Stimulus, TrialItem
from studyapp.stimuli.catch_clips import CATCH_PER_BASE, catch_bases, catch_clips
from studyapp.stimuli.build import Build, build_stimuli
from studyapp.stimuli.config import load_config

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "studies" / "demo" / "ranking.yaml"
OVERRIDES = ["actions=[walk,wave]", "render.size=48", "frames=20"]


@pytest.fixture
def built(db, media_root, tmp_path):
    config = load_config(DEMO, OVERRIDES)
    result = build_stimuli(config, tmp_path / "b", cache=tmp_path / "cache")
    return config, result, tmp_path


def test_a_build_makes_a_catch_family_of_every_source(built):
    config, result, tmp_path = built
    study = result.study
    catch = list(study.stimuli.filter(role=Stimulus.Role.CATCH))
    per_action = Counter(s.action for s in catch)
    assert per_action == {"walk": CATCH_PER_BASE * 3, "wave": CATCH_PER_BASE * 3}
    assert {s.source for s in catch} == {"broken"}
    judged = set(study.stimuli.judged().values_list("motion_hash", flat=True))
    assert not judged & {s.motion_hash for s in catch}
    # The bases: one clip of each source per action, none of them judged, cached.
    build = Build(config, tmp_path / "b", cache=tmp_path / "cache")
    groups = [(source, *build.source_motions(source)[:2]) for source in config.sources]
    family = catch_clips(build, groups, build.real_base()[1])
    assert len(family) == len(catch) and all(role == "catch" for _, role, _ in family)
    kinds = [motion.meta["broken"] for motion, _, _ in family]
    assert all(a != b for a, b in zip(kinds[::2], kinds[1::2]))  # two kinds per base
    assert len(set(kinds)) >= 3
    bases = {motion.content_hash() for source, motions, meta in groups
             for motion in catch_bases(build, source, motions, meta)}
    assert len(bases) == 2 * 3 and not bases & judged
    assert len(list((tmp_path / "cache" / "motions").glob("*-catch-*.npz"))) == 3
    # A rebuild draws nothing new and renders nothing.
    again = build_stimuli(config, tmp_path / "b", cache=tmp_path / "cache")
    assert again.rendered == 0 and again.unchanged


def test_each_participant_gets_the_least_used_catch_clip(built, make_bot):
    _, result, _ = built
    study = result.study
    catch = set(study.stimuli.filter(role=Stimulus.Role.CATCH).values_list("pk", flat=True))
    for _ in range(len(catch)):
        make_bot(study).join()
    shown = Counter(TrialItem.objects.filter(stimulus__in=catch)
                    .values_list("stimulus", flat=True))
    assert set(shown) == catch and set(shown.values()) == {1}  # nobody shares one yet
    make_bot(study).join()
    shown = Counter(TrialItem.objects.filter(stimulus__in=catch)
                    .values_list("stimulus", flat=True))
    assert sorted(shown.values()) == [1] * (len(catch) - 1) + [2]


def test_the_dry_run_counts_the_family(db, media_root, tmp_path):
    config = load_config(DEMO, OVERRIDES)
    lines = []
    Build(config, tmp_path / "b", log=lines.append, cache=tmp_path / "cache").run(dry_run=True)
    assert f"{CATCH_PER_BASE * 3} catch" in lines[-1]


def test_the_versions_kept_match_the_judged_clips_payload_numbers(built):
    """Of four versions per base, the two kept bring the family's payload numbers (mean and
    mean square, standardised on the judged clips) nearer the judged clips' than the two
    nearest their base would."""
    import numpy as np

    from motion import perturb
    from studyapp.stimuli.catch_clips import _numbers, keep_like

    config, _, tmp_path = built
    build = Build(config, tmp_path / "b", cache=tmp_path / "cache")
    groups = [(source, *build.source_motions(source)[:2]) for source in config.sources]
    framing = build.real_base()[1]
    judged = [m for _, motions, _ in groups for m in motions]
    bases = [m for source, motions, meta in groups
             for m in catch_bases(build, source, motions, meta)]
    candidates = perturb.catch_candidates(bases, 4, np.random.default_rng(0))
    rows = _numbers(judged, framing)
    names = sorted(rows[0])
    table = np.array([[r[n] for n in names] for r in rows])
    mean, spread = table.mean(axis=0), np.where(table.std(axis=0) > 0, table.std(axis=0), 1)

    def mismatch(motions):
        z = (np.array([[r[n] for n in names] for r in _numbers(motions, framing)]) - mean) / spread
        return float((z.mean(axis=0) ** 2).sum() + (((z ** 2).mean(axis=0) - 1) ** 2).sum())

    kept = keep_like(judged, candidates, framing)
    assert len(kept) == 2 * len(bases)
    assert mismatch(kept) < mismatch([m for versions in candidates for m in versions[:2]])

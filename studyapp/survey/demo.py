"""Build the embedded demo: train methods on the demo data, sample, render, register.

One study of every type is made from the same clips, so a newcomer sees all five:
ranking, fake or real (in the ``mesh`` style when it is available), realism rating
with scoring standards, realism rating with a real reference, and pairwise preference.
Besides the rated clips, each action gets a real reference clip, five scoring-standard
examples (a real clip degraded step by step) and an obviously broken catch clip.

Each step keeps its output under ``<var>/demo/`` and is skipped when that output is
already there for the same plan, so a second ``make demo`` serves within seconds.
"""

from __future__ import annotations

import json
import secrets
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from django.contrib.auth import get_user_model
from django.db import transaction

from generation.datasets import get_dataset
from generation.formats import npz
from generation.methods import get_method, load_checkpoint
from generation.sampling import sample_real
from rendering import list_styles, render_set
from studyapp.survey.models import Participant, ScoringStandard, Study
from studyapp.survey.stimuli import register_clips
from studyapp.survey.study_types.rating_standards import default_descriptions

DEMO_SLUG = "demo-ranking"
STUDY_TYPES = ("ranking", "fake_or_real", "rating_standards", "rating_reference", "pairwise")
TITLES = {
    "ranking": "Which motion looks best?",
    "fake_or_real": "Real or generated?",
    "rating_standards": "How realistic is this motion?",
    "rating_reference": "How realistic is this motion, next to a real one?",
    "pairwise": "Which of two motions looks better?",
}
# Joint jitter, as a share of the figure's extent, of the example clip of each score;
# the catch clip is broken further still.
STANDARD_NOISE = {5: 0.0, 4: 0.01, 3: 0.03, 2: 0.07, 1: 0.18}
CATCH_NOISE = 0.25
CATCH_SOURCE = "broken"


@dataclass
class DemoPlan:
    """What the demo builds; every field changes what is built."""

    dataset: str = "demo"
    data_root: str | None = None
    actions: list[str] | None = None  # None: every action of the dataset
    methods: list[str] = field(default_factory=lambda: ["a2m", "cond_gru"])
    preset: str = "demo"
    iters: int = 400
    clips_per_source: int = 2
    frames: int | None = None  # None: the dataset's clip length
    size: int = 480
    seed: int = 0
    slug: str = DEMO_SLUG  # of the ranking study; the others share its prefix
    study_types: tuple[str, ...] = STUDY_TYPES
    checks: bool = True  # a practice, a catch and a repeated trial; closing questions
    fake_or_real_style: str = "mesh"  # falls back to stick when not registered
    fake_or_real_trials: int = 12

    def key(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)

    def slug_of(self, study_type: str) -> str:
        if study_type == "ranking":
            return self.slug
        prefix = self.slug.removesuffix("-ranking")
        return f"{prefix}-{study_type.replace('_', '-')}"


def demo_studies(plan: DemoPlan) -> list[Study]:
    """Return the plan's studies that exist, in the plan's order."""
    slugs = [plan.slug_of(t) for t in plan.study_types]
    studies = {s.slug: s for s in Study.objects.filter(slug__in=slugs)}
    return [studies[plan.slug_of(t)] for t in plan.study_types if plan.slug_of(t) in studies]


def build_demo(plan: DemoPlan, root: Path, log=print) -> Study:
    """Build (or reuse) the demo studies of a plan under ``root``; return the first.

    The first is the ranking study when the plan has one; :func:`demo_studies` lists all.
    """
    root.mkdir(parents=True, exist_ok=True)
    plan_file = root / "plan.json"
    existing = demo_studies(plan)
    if len(existing) == len(plan.study_types) and all(s.stimuli.exists() for s in existing):
        if plan_file.is_file() and plan_file.read_text() == plan.key():
            log(f"demo: studies {', '.join(s.slug for s in existing)} are built; reusing them")
            return existing[0]

    dataset = get_dataset(plan.dataset, plan.data_root)
    actions = plan.actions or dataset.actions()
    frames = plan.frames or dataset.clip_frames
    training = dataset.clips(actions=actions)
    log(f"demo: {len(training)} training clips of {len(actions)} actions from {plan.dataset!r}")

    # Two more real clips per action than are rated: a reference, and the base of the
    # scoring-standard examples and of the catch clip.
    n = plan.clips_per_source
    real = sample_real(dataset, actions, n + 2, frames, plan.seed)
    groups = [real[i : i + n + 2] for i in range(0, len(real), n + 2)]
    sets = [[m for group in groups for m in group[:n]]]
    for name in plan.methods:
        method = _trained(name, plan, dataset, training, root / "checkpoints", log)
        wanted = [a for a in actions for _ in range(n)]
        sets.append(method.sample(wanted, frames=frames, seed=plan.seed))
    for motions in sets:
        npz.save(root / "motions" / f"{motions[0].source}.npz", motions)
    rated = [m for group in sets for m in group]
    extras = _extras([group[n] for group in groups], [group[n + 1] for group in groups], plan)

    log(f"demo: rendering {len(rated)} clips and {len(extras)} references, examples, catches")
    stick = _render(rated, extras, root / "renders", "stick", plan.size)
    clips = {"stick": stick}
    if "fake_or_real" in plan.study_types:
        style = plan.fake_or_real_style if plan.fake_or_real_style in list_styles() else "stick"
        if style != "stick":
            log(f"demo: rendering the fake-or-real clips in the {style!r} style")
            catch = [clip for clip in extras if clip.get("is_catch")]
            clips[style] = _render(rated, catch, root / f"renders-{style}", style, plan.size)
        clips["fake_or_real"] = clips[style]

    with transaction.atomic():
        slugs = [plan.slug_of(t) for t in plan.study_types]
        # The demo's own answers go with it when its plan changes; answers are
        # otherwise protected (TrialItem.stimulus is PROTECT).
        Participant.objects.filter(study__slug__in=slugs).delete()
        Study.objects.filter(slug__in=slugs).delete()
        studies = [
            _create(study_type, plan, dataset, clips.get(study_type, stick), actions)
            for study_type in plan.study_types
        ]
    plan_file.write_text(plan.key())
    return studies[0]


def _create(study_type, plan, dataset, clips, actions) -> Study:
    """Create one demo study of ``study_type`` from the rendered clips."""
    checks = plan.checks
    fields = {
        "dataset": plan.dataset,
        "data_note": (
            "The motions in this study are synthetic: procedurally generated demo data "
            "and models trained on it."
            if dataset.synthetic
            else ""
        ),
        "practice": checks,
        "catch_trials": 1 if checks else 0,
        "repeat_trials": 1 if checks else 0,
        "ask_demographics": checks,
    }
    if study_type in ("ranking", "rating_standards", "rating_reference"):
        fields["clips_per_trial"] = 1 + len(plan.methods)
    if study_type == "fake_or_real":
        fields["trials_per_participant"] = plan.fake_or_real_trials
    if study_type == "pairwise":
        fields["allow_ties"] = True
    study = Study.objects.create_study(
        study_type, plan.slug_of(study_type), TITLES[study_type], **fields
    )
    wanted = [
        clip
        for clip in clips
        if clip["role"] == "rated"
        or (clip["role"] == "catch" and checks)
        or (clip["role"] == "reference" and study_type == "rating_reference")
        or (clip["role"] == "example" and study_type == "rating_standards")
    ]
    stimuli = register_clips(study, wanted)
    if study_type == "rating_standards":
        for action in actions:
            examples = {
                clip["score"]: stimulus
                for clip, stimulus in zip(wanted, stimuli)
                if clip["role"] == "example" and clip["action"] == action
            }
            ScoringStandard.objects.set_standards(
                study, action, examples, default_descriptions(action.replace("_", " "))
            )
    return study


def _extras(references, bases, plan) -> list[dict]:
    """Return the reference, scoring-standard example and catch motions, as clip specs."""
    rng = np.random.default_rng(plan.seed + 1)
    out = []
    if "rating_reference" in plan.study_types:
        out += [{"motion": m, "role": "reference", "is_reference": True} for m in references]
    for base in bases:
        if "rating_standards" in plan.study_types:
            for score, noise in STANDARD_NOISE.items():
                example = degrade(base, noise, rng, "standard_example")
                out.append(
                    {"motion": example, "role": "example", "score": score,
                     "is_standard_example": True}
                )
        if plan.checks:
            broken = degrade(base, CATCH_NOISE, rng, CATCH_SOURCE)
            out.append({"motion": broken, "role": "catch", "is_catch": True})
    return out


def degrade(motion, noise: float, rng, source: str):
    """Return ``motion`` as ``source``, each joint jittered by ``noise`` x the figure's size."""
    joints = motion.joints
    extent = float(np.ptp(joints.reshape(-1, joints.shape[-1]), axis=0).max())
    jitter = rng.normal(scale=noise * extent, size=joints.shape) if noise > 0 else 0.0
    joints = (joints + jitter).astype(np.float32)
    return motion.with_joints(joints, source=source, meta=dict(motion.meta))


def _render(rated, extras, folder, style, size) -> list[dict]:
    """Render the rated motions, then the extras in the same framing; return clip specs."""
    report = render_set(rated, folder, style=style, size=size)
    more = None
    if extras:
        motions = [extra["motion"] for extra in extras]
        framing = report.framing
        more = render_set(motions, folder / "extras", style=style, size=size, framing=framing)
    failures = report.failures + (more.failures if more else [])
    if failures:
        raise RuntimeError(f"demo: clips failed to render in the {style!r} style: {failures}")
    specs = [_clip(rated[c.index], c) | {"role": "rated"} for c in report.clips]
    for rendered in more.clips if more else []:
        extra = extras[rendered.index]
        roles = {k: v for k, v in extra.items() if k != "motion"}
        specs.append(_clip(extra["motion"], rendered) | roles)
    return specs


def _trained(name, plan, dataset, training, folder, log):
    """Return a method trained on the demo clips, from its checkpoint when there is one."""
    path = folder / f"{name}.pt"
    if path.is_file():
        method = load_checkpoint(path)
        if method.iteration >= plan.iters:
            log(f"demo: reusing {path}")
            return method
    cls = get_method(name)
    method = cls(
        cls.Config.preset(plan.preset),
        skeleton=dataset.skeleton,
        actions=sorted({m.action for m in training}, key=dataset.actions().index),
        fps=dataset.clip_fps,
        frames=plan.frames or dataset.clip_frames,
    )
    log(f"demo: training {name} for {plan.iters} iterations")
    method.fit(training, iters=plan.iters, seed=plan.seed)
    method.save(path)
    return method


def _clip(motion, rendered) -> dict:
    return {
        "action": motion.action,
        "source": motion.source,
        "video": rendered.video,
        "poster": rendered.poster,
        "duration": rendered.duration,
        "motion_hash": rendered.motion_hash,
        "video_hash": rendered.video_hash,
    }


def ensure_admin(root: Path) -> tuple[str, str]:
    """Create the demo's admin account once; return (username, password)."""
    secret = root / "admin-password.txt"
    username = "admin"
    if not secret.is_file():
        root.mkdir(parents=True, exist_ok=True)
        secret.write_text(secrets.token_urlsafe(9))
        secret.chmod(0o600)
    password = secret.read_text().strip()
    users = get_user_model().objects
    user = users.filter(username=username).first()
    if user is None:
        users.create_superuser(username, "", password)
    elif not user.check_password(password):
        user.set_password(password)
        user.save()
    return username, password

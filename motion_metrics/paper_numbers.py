"""The numbers the seed papers report, copied from their tables, to print beside ours.

Each :class:`PaperTable` names its paper and table, the dataset and split behind it,
and one :class:`PaperRow` per method: our registry key when we implement the method
(``None`` otherwise), the paper's name for it, and its values keyed by our metric names
(``mmd_avg``, ``mmd_seq``, ``accuracy``, ``fid``, ``diversity``, ``multimodality``) or,
for per-class accuracies, by action. ``real`` rows are the papers' "Real motions".
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class PaperRow:
    """One method's reported values (and 95 % half-widths where the paper gives them)."""

    method: str | None  # our registry key, or None for methods we do not implement
    label: str  # the paper's name
    values: dict[str, float]
    ci: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class PaperTable:
    """One table of a seed paper."""

    key: str
    source: str  # "seed 004, Table 1"
    dataset: str  # what the paper measured on
    metrics: tuple[str, ...]
    rows: tuple[PaperRow, ...]
    real: PaperRow | None = None

    def row(self, method: str) -> PaperRow | None:
        """Return the row of our method ``method``, or ``None`` when the table lacks it."""
        return next((row for row in self.rows if row.method == method), None)


def _mmd(avg: float, seq: float) -> dict[str, float]:
    return {"mmd_avg": avg, "mmd_seq": seq}


# Seed 004 (SA-GCN, ECCV 2020), Table 1: MMD on Human3.6M (2D, 15 joints, 50 frames).
SA_GCN_TABLE_1 = PaperTable(
    key="004_table_1",
    source="seed 004, Table 1",
    dataset="Human3.6M 2D, 10 classes, test subject S11",
    metrics=("mmd_avg", "mmd_seq"),
    rows=(
        PaperRow(None, "E2E [Wichers et al.]", _mmd(0.991, 0.805)),
        PaperRow(None, "EPVA [Wichers et al.]", _mmd(0.996, 0.806)),
        PaperRow(None, "adv-EPVA [Wichers et al.]", _mmd(0.977, 0.792)),
        PaperRow("skeleton_vae", "SkeletonVAE", _mmd(0.452, 0.467)),
        PaperRow("skeleton_gan", "SkeletonGAN", _mmd(0.419, 0.436)),
        PaperRow("c_skeleton_gan", "c-SkeletonGAN", _mmd(0.195, 0.218)),
        PaperRow("sa_gcn", "SA-GCN", _mmd(0.146, 0.134)),
    ),
)

H36M_CLASSES = ("Directions", "Discussion", "Eating", "Greeting", "Phoning", "Posing",
                "Sitting", "SittingDown", "Smoking", "Walking")


def _per_class(values: tuple[float, ...], average: float) -> dict[str, float]:
    return {**dict(zip(H36M_CLASSES, values)), "accuracy": average}


# Seed 004, Table 2: accuracy of the authors' classifier (the video discriminator's
# architecture, pretrained on real data) on generated motions, per class and on average.
SA_GCN_TABLE_2 = PaperTable(
    key="004_table_2",
    source="seed 004, Table 2",
    dataset="Human3.6M 2D, 10 classes, test subject S11",
    metrics=H36M_CLASSES + ("accuracy",),
    rows=(
        PaperRow("skeleton_vae", "SkeletonVAE", _per_class(
            (0.37, 0.01, 0.51, 0.47, 0.10, 0.03, 0.17, 0.33, 0.01, 0.01), 0.201)),
        PaperRow("skeleton_gan", "SkeletonGAN", _per_class(
            (0.35, 0.29, 0.72, 0.66, 0.46, 0.09, 0.32, 0.71, 0.14, 0.02), 0.376)),
        PaperRow("c_skeleton_gan", "c-SkeletonGAN", _per_class(
            (0.34, 0.44, 0.57, 0.56, 0.52, 0.25, 0.67, 1.00, 0.50, 0.03), 0.488)),
        PaperRow("sa_gcn", "SA-GCN", _per_class(
            (0.42, 0.40, 0.78, 0.55, 0.72, 0.61, 0.95, 0.79, 0.52, 0.18), 0.593)),
    ),
)

# Seed 003 (c-SkeletonGAN, AAAI 2020), Table 1: MMD on Human3.6M; the E2E/EPVA models
# without seed motion, as ours (with a seed frame they reach 0.304-0.339).
C_SKELETON_GAN_TABLE_1 = PaperTable(
    key="003_table_1",
    source="seed 003, Table 1",
    dataset="Human3.6M 2D, 10 classes, test subject S11",
    metrics=("mmd_avg", "mmd_seq"),
    rows=(
        PaperRow(None, "E2E, with seed motion", _mmd(0.304, 0.305)),
        PaperRow(None, "EPVA, with seed motion", _mmd(0.305, 0.326)),
        PaperRow(None, "EPVA-adv, with seed motion", _mmd(0.339, 0.335)),
        PaperRow(None, "E2E, without seed motion", _mmd(0.991, 0.805)),
        PaperRow(None, "EPVA, without seed motion", _mmd(0.996, 0.806)),
        PaperRow(None, "EPVA-adv, without seed motion", _mmd(0.977, 0.792)),
        PaperRow("skeleton_vae", "Habibie et al., 2017", _mmd(0.452, 0.467)),
        PaperRow("skeleton_gan", "Cai et al., 2018", _mmd(0.419, 0.436)),
        PaperRow("c_skeleton_gan", "Ours (c-SkeletonGAN)", _mmd(0.195, 0.218)),
    ),
)


def _a2m(fid, acc, div, mm) -> tuple[dict[str, float], dict[str, float]]:
    """Return values and 95 % half-widths from (value, half-width) pairs of A2M's Table 1."""
    pairs = dict(zip(("fid", "accuracy", "diversity", "multimodality"), (fid, acc, div, mm)))
    return {k: v[0] for k, v in pairs.items()}, {k: v[1] for k, v in pairs.items()}


def _a2m_row(method, label, *pairs) -> PaperRow:
    values, ci = _a2m(*pairs)
    return PaperRow(method, label, values, ci)


# Seed 000 (Action2Motion, ACM MM 2020), Table 1, HumanAct12 columns (20 repeats, 95 % CI).
A2M_TABLE_1 = PaperTable(
    key="000_table_1",
    source="seed 000, Table 1, HumanAct12 columns",
    dataset="HumanAct12 (24 SMPL joints, 60 frames, 12 classes)",
    metrics=("fid", "accuracy", "diversity", "multimodality"),
    real=_a2m_row(None, "Real motions", (0.092, 0.007), (0.997, 0.001), (6.853, 0.053),
                  (2.449, 0.038)),
    rows=(
        _a2m_row("cond_gru", "CondGRU", (40.61, 0.144), (0.080, 0.002), (2.381, 0.020),
                 (2.341, 0.036)),
        _a2m_row("two_stage_gan", "Two-stage GAN", (10.48, 0.089), (0.421, 0.006),
                 (5.960, 0.049), (2.805, 0.036)),
        _a2m_row("act_mocogan", "Act-MoCoGAN", (5.610, 0.113), (0.793, 0.004), (6.752, 0.071),
                 (1.055, 0.017)),
        _a2m_row("a2m_xyz", "Ours w/o Lie", (3.299, 0.079), (0.656, 0.005), (6.742, 0.046),
                 (4.248, 0.037)),
        _a2m_row("a2m", "Ours (Action2Motion)", (2.458, 0.079), (0.923, 0.002), (7.032, 0.038),
                 (2.870, 0.037)),
    ),
)

TABLES = {table.key: table for table in
          (SA_GCN_TABLE_1, SA_GCN_TABLE_2, C_SKELETON_GAN_TABLE_1, A2M_TABLE_1)}

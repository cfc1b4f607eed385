from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from motion.body_models import ENV_VAR
from motion.formats import FormatError, format_options, list_formats, load_motions, npz
from motion.formats.bvh import UNITS
from motion.motion import MotionError

# Command-line flags that become format options, and the option each one becomes.
FORMAT_FLAGS = {
    "skeleton": "skeleton",
    "classes": "classes_path",
    "action_names": "action_names",
    "file_fps": "file_fps",
    "action": "action",
    "joint_map": "mapping",
    "scale": "scale",
    "up": "up",
    "texts": "texts",
    "mean": "mean",
    "std": "std",
    "body_models": "body_models",
    "gender": "gender",
    "person": "person",
    "frame": "frame",
    "hands": "hands",
}


class Command(BaseCommand):
    help = (
        "Convert motions from other codebases or motion capture into one interchange .npz: "
        "MDM's results.npy and meshes, HumanML3D joints or feature vectors, folders of "
        "joint arrays (MoMask, T2M-GPT, MotionGPT, MotionDiffuse), AMASS, MotionCritic, "
        "ACTOR, Action2Motion, BVH, pose estimators (WHAM, 4D-Humans/PHALP, VIBE, TRAM), "
        "AIST++, PHC motion libraries, AMP poselib files, or --format auto to detect it. Files of a folder that "
        "cannot be read are reported by name; the others are written."
    )

    def add_arguments(self, parser):
        parser.add_argument("files", nargs="+", metavar="FILE_OR_DIR",
                            help="Files or folders to import.")
        parser.add_argument("--format", required=True, choices=list_formats(),
                            help="The layout of the files (auto: detect it from the content "
                                 "and say what was found).")
        parser.add_argument("--out", required=True, metavar="F.npz", help="The .npz file to write.")
        parser.add_argument("--skeleton",
                            help="Project skeleton (smpl22, smpl24, kit21, humanact12, h36m17). "
                                 "bvh: map the files' joints onto it (default: each file's own "
                                 "hierarchy); joints, a2m, mdm: when the joint count does not "
                                 "tell; npz: checked.")
        parser.add_argument("--fps", type=float, help="Resample to this frame rate "
                                                      "(default: keep the files' rate).")
        parser.add_argument("--file-fps", type=float,
                            help="Frame rate of files that hold none (default: the codebase's: "
                                 "20, KIT-ML 12.5; a2m: 20 for humanact12, 25 for h36m17).")
        parser.add_argument("--source", help="Source of the motions: 'real' or a method key "
                                             "(default: the format's, e.g. mdm, a2m, real).")
        parser.add_argument("--action", help="The action of motions that name none "
                                             "(default: bvh: the prompt or file name; "
                                             "others: unknown).")
        parser.add_argument("--texts", metavar="PROMPTS",
                            help="joints, bvh: the prompts, one line per file (in name order, "
                                 "or line k+1 for files named sample<k>...) or a CSV with file "
                                 "and text columns (default: prompts.txt/.csv beside the files, "
                                 "else joints: a file name that spells one, "
                                 "a_person_is_boxing.npy).")
        parser.add_argument("--classes", metavar="CLASSES.npy",
                            help="a2m (required): each motion's class index, shape (N,).")
        parser.add_argument("--action-names", metavar="A,B,...",
                            help="a2m, actor: names of classes 0, 1, ... (default: HumanAct12's "
                                 "12 classes for 24 joints or 12 classes, else class0, ...).")
        parser.add_argument("--mean", metavar="Mean.npy",
                            help="humanml3d_vec: de-normalise features with this mean ...")
        parser.add_argument("--std", metavar="Std.npy", help="... and this std.")
        parser.add_argument("--body-models", metavar="DIR",
                            help=f"amass, smplx, motioncritic, actor, mdm meshes, wham, phalp, "
                                 f"vibe, tram, aistpp, phc: the folder of SMPL / SMPL+H / "
                                 f"SMPL-X model files "
                                 f"(default: ${ENV_VAR}).")
        parser.add_argument("--gender", choices=("neutral", "male", "female"),
                            help="amass, smplx: the body model's gender (default: the "
                                 "file's).")
        parser.add_argument("--joints-only", action="store_true",
                            help="Drop the body surfaces imports carry (smaller files; the "
                                 "mesh style then draws its own body).")
        parser.add_argument("--joint-map", metavar="JOINT=BVH_JOINT,...",
                            help="bvh: skeleton joints to take from BVH joints the built-in "
                                 "maps miss, e.g. Spine=Chest,Thorax=Neck.")
        parser.add_argument("--scale",
                            help=f"bvh: metres per file unit, a unit ({', '.join(UNITS)}) or "
                                 "auto (default: the unit that makes the body about 1.7 m).")
        parser.add_argument("--up", choices=("x", "y", "z"), help="bvh: the files' up axis "
                                                                  "(default: y).")
        parser.add_argument("--person", metavar="ID",
                            help="wham, phalp, vibe: the tracked person to import (default: "
                                 "every track, each a motion; the notes list the ids).")
        parser.add_argument("--frame", choices=("world", "camera"),
                            help="wham: the world frame WHAM estimates (default) or the "
                                 "camera's.")
        parser.add_argument("--hands", action="store_true", default=None,
                            help="smplx: keep the 30 finger joints (a 52-joint skeleton; "
                                 "default: the 22 body joints, smpl22).")
        parser.add_argument("--per-skeleton", action="store_true",
                            help="Write one file per skeleton (OUT_<skeleton>.npz) when the "
                                 "files hold several (default: refuse, naming them).")

    def handle(self, *args, **options):
        fmt, files = options["format"], options["files"]
        load_options = format_flags(fmt, options)
        if options["joints_only"] and ("vertices" in format_options(fmt)):
            load_options["vertices"] = False
        motions, problems = [], []
        try:
            for path in files:
                loaded = load_motions(path, fmt, fps=options["fps"], source=options["source"],
                                      **load_options)
                for note in getattr(loaded, "notes", []):
                    (self.stderr if note.startswith("warning") else self.stdout).write(note)
                problems.extend(getattr(loaded, "problems", []))
                motions.extend(loaded)
        except (FormatError, MotionError) as exc:
            raise CommandError(str(exc)) from None
        for problem in problems:
            self.stderr.write(f"skipped: {problem}")
        if options["joints_only"]:
            motions = [m.with_joints(m.joints, vertices=None, faces=None, meta=dict(m.meta))
                       for m in motions]
        groups: dict[str, list] = {}
        for motion in motions:
            groups.setdefault(motion.skeleton, []).append(motion)
        if len(groups) > 1 and not options["per_skeleton"]:
            found = ", ".join(f"{len(group)} of {name}" for name, group in groups.items())
            raise CommandError(
                f"the files hold motions of {len(groups)} skeletons ({found}); one .npz holds "
                "one skeleton. Map them onto one (BVH files: --skeleton smpl22; others are "
                "checked against it), or pass --per-skeleton to write one file per skeleton "
                f"({Path(options['out']).stem}_<skeleton>.npz)")
        out = Path(options["out"])
        for name, group in groups.items():
            target = out.with_name(f"{out.stem}_{name}{out.suffix}") if len(groups) > 1 else out
            self.write(group, target, problems)

    def write(self, motions, out: Path, problems):
        rates = sorted({motion.fps for motion in motions})
        if len(rates) > 1:
            raise CommandError(f"the files have frame rates {', '.join(map(str, rates))}; "
                               "pass --fps F to resample them to one")
        sources = sorted({motion.source for motion in motions})
        if len(sources) > 1:
            raise CommandError(f"the files hold motions of sources {', '.join(sources)}; one "
                               ".npz holds one source: pass --source NAME (e.g. real, or the "
                               "method that made them), or import each kind on its own")
        try:
            path = npz.save(out, motions)
        except (FormatError, MotionError) as exc:
            raise CommandError(str(exc)) from None
        first = motions[0]
        actions = sorted({m.action for m in motions})
        prompts = sum(1 for m in motions if m.text)
        bodies = sum(1 for m in motions if m.has_body)
        extras = [f"{prompts} with prompts"] if prompts else []
        extras += [f"{bodies} with body surfaces"] if bodies else []
        self.stdout.write(
            f"wrote {len(motions)} {first.skeleton} motions at {first.fps:g} fps, source "
            f"{first.source!r} ({', '.join(actions[:8])}{', ...' if len(actions) > 8 else ''})"
            f"{'; ' + ', '.join(extras) if extras else ''} to {path}"
            f"{f'; skipped {len(problems)} (see above)' if problems else ''}"
        )


def format_flags(fmt: str, options: dict) -> dict:
    """Return the format options given on the command line, checked against the format."""
    accepted = format_options(fmt)
    chosen = {}
    for flag, option in FORMAT_FLAGS.items():
        value = options[flag]
        if value is None:
            continue
        if option not in accepted:
            owners = [f for f in list_formats() if f != "auto" and option in format_options(f)]
            raise CommandError(f"--{flag.replace('_', '-')} is not an option of --format {fmt} "
                               f"(it is for {', '.join(owners)})")
        if flag == "action_names":
            value = [name.strip() for name in value.split(",")]
        elif flag == "joint_map":
            value = parse_joint_map(value)
        chosen[option] = value
    return chosen


def parse_joint_map(text: str) -> dict[str, str]:
    """Parse ``Spine=Chest,Thorax=Neck`` into ``{"Spine": "Chest", "Thorax": "Neck"}``."""
    mapping = {}
    for part in text.split(","):
        joint, sign, bvh_joint = part.partition("=")
        if not sign or not joint.strip() or not bvh_joint.strip():
            raise CommandError(f"--joint-map {text!r}: write JOINT=BVH_JOINT pairs, e.g. "
                               "Spine=Chest,Thorax=Neck")
        mapping[joint.strip()] = bvh_joint.strip()
    return mapping

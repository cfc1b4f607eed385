from django.core.management.base import BaseCommand, CommandError

from generation.formats import FormatError, list_formats, load_motions, npz
from generation.formats.bvh import UNITS
from generation.motion import MotionError

# The flags that only some formats take, and the option each one becomes.
FORMAT_FLAGS = {
    "classes": ("a2m", "classes_path"),
    "action_names": ("a2m", "action_names"),
    "file_fps": ("a2m", "file_fps"),
    "action": ("bvh", "action"),
    "joint_map": ("bvh", "mapping"),
    "scale": ("bvh", "scale"),
}


class Command(BaseCommand):
    help = (
        "Convert motions from other codebases or motion capture (an interchange .npz, "
        "Action2Motion's .npy arrays, BVH files) into one interchange .npz."
    )

    def add_arguments(self, parser):
        parser.add_argument("files", nargs="+", metavar="FILE",
                            help="Files to import: one for a2m, one or more for npz and bvh "
                                 "(one motion per BVH file).")
        parser.add_argument("--format", required=True, choices=list_formats(),
                            help="npz: an interchange file (checked and rewritten); a2m: "
                                 "Action2Motion joints (N, T, J*3); bvh: BVH motion capture.")
        parser.add_argument("--out", required=True, metavar="F.npz", help="The .npz file to write.")
        parser.add_argument("--skeleton",
                            help="Project skeleton. bvh: the one to map onto (required); a2m: "
                                 "when the joint count does not tell; npz: checked.")
        parser.add_argument("--fps", type=float, help="Resample to this frame rate "
                                                      "(default: keep the files' rate).")
        parser.add_argument("--source", help="Source of the motions: 'real' or a method key "
                                             "(default: npz: the file's; a2m: a2m; bvh: real).")
        parser.add_argument("--classes", metavar="CLASSES.npy",
                            help="a2m (required): each motion's class index, shape (N,).")
        parser.add_argument("--action-names", metavar="A,B,...",
                            help="a2m: names of classes 0, 1, ... (default: HumanAct12's 12 "
                                 "classes for 24 joints, else class0, class1, ...).")
        parser.add_argument("--file-fps", type=float,
                            help="a2m: frame rate of the arrays (default: 20 for humanact12, "
                                 "25 for h36m17).")
        parser.add_argument("--action", help="bvh (required): the action the files show.")
        parser.add_argument("--joint-map", metavar="JOINT=BVH_JOINT,...",
                            help="bvh: skeleton joints to take from BVH joints the built-in "
                                 "CMU and Mixamo maps miss, e.g. Spine=Chest,Thorax=Neck.")
        parser.add_argument("--scale",
                            help=f"bvh: metres per file unit, a unit ({', '.join(UNITS)}) or "
                                 "auto (default: the unit that makes the body about 1.7 m).")

    def handle(self, *args, **options):
        fmt, files = options["format"], options["files"]
        load_options = format_options(fmt, options)
        if fmt == "a2m" and len(files) != 1:
            raise CommandError(f"--format a2m imports one file with its --classes; "
                               f"got {len(files)}")
        if fmt == "a2m" and "classes_path" not in load_options:
            raise CommandError("--format a2m needs --classes CLASSES.npy, each motion's "
                               "class index")
        if fmt == "bvh" and not (options["skeleton"] and options["action"]):
            raise CommandError("--format bvh needs --skeleton (h36m17 or humanact12) and "
                               "--action (the action the files show)")
        if options["skeleton"]:
            load_options["skeleton"] = options["skeleton"]
        try:
            motions = [motion for path in files
                       for motion in load_motions(path, fmt, fps=options["fps"],
                                                  source=options["source"], **load_options)]
            rates = sorted({motion.fps for motion in motions})
            if len(rates) > 1:
                raise CommandError(f"the files have frame rates {', '.join(map(str, rates))}; "
                                   "pass --fps F to resample them to one")
            path = npz.save(options["out"], motions)
        except (FormatError, MotionError) as exc:
            raise CommandError(str(exc)) from None
        actions = sorted({m.action for m in motions})
        first = motions[0]
        self.stdout.write(
            f"wrote {len(motions)} {first.skeleton} motions at {first.fps:g} fps, source "
            f"{first.source!r} ({', '.join(actions)}) to {path}"
        )


def format_options(fmt: str, options: dict) -> dict:
    """Return the options of the format's loader given on the command line."""
    chosen = {}
    for flag, (owner, option) in FORMAT_FLAGS.items():
        value = options[flag]
        if value is None:
            continue
        if owner != fmt:
            raise CommandError(f"--{flag.replace('_', '-')} is for --format {owner}, not {fmt}")
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

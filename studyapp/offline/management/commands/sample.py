import numpy as np
from django.core.management.base import BaseCommand, CommandError

from motion.datasets import DatasetError, get_dataset
from motion.formats import npz
from generation.methods import CheckpointError, MethodError, get_method, list_methods
from generation.sampling import SamplingError, choose, sample_method, sample_real
from motion.skeletons import get_skeleton

REAL = "real"


class Command(BaseCommand):
    help = (
        "Write N motions per action to an interchange .npz, from a trained method "
        "(--checkpoint) or, with source 'real', from a dataset's clips."
    )

    def add_arguments(self, parser):
        parser.add_argument("source", help=f"'{REAL}' or a method key: {', '.join(list_methods())}.")
        parser.add_argument("--checkpoint", help="Checkpoint of the method (from `train`).")
        parser.add_argument("--dataset", help="Dataset to draw real clips from (source 'real').")
        parser.add_argument("--data-root", help="Folder of the dataset (default: its usual place).")
        parser.add_argument("--subjects", help="Comma-separated subjects for real clips (default: all).")
        parser.add_argument("--action", action="append", required=True,
                            help="Action; repeat or comma-separate for several, or 'all'.")
        parser.add_argument("--n", type=int, default=1, help="Motions per action.")
        parser.add_argument("--frames", type=int, help="Frames per motion (default: the source's).")
        parser.add_argument("--fps", type=float, help="Frame rate of real clips (default: the dataset's).")
        parser.add_argument("--seed", type=int, default=0, help="Same seed, same motions.")
        parser.add_argument("--out", help="The .npz file to write (required unless --list-modes).")
        group = parser.add_argument_group("method-specific options")
        group.add_argument("--bone-lengths-from", metavar="FILE.npz",
                           help="a2m: draw with the bone lengths of the motions in this file "
                                "(another body; seed 000 Fig. 6).")
        group.add_argument("--mix", metavar="A=W,B=W",
                           help="c_skeleton_gan, sa_gcn: a soft label mixing actions, e.g. "
                                "Walking=0.5,Phoning=0.5.")
        group.add_argument("--mode", type=int, metavar="K",
                           help="odmo: sample from mode K of the action (see --list-modes).")
        group.add_argument("--interpolate", metavar="K1,K2",
                           help="odmo: interpolate between modes K1 and K2 of the action in "
                                "--n steps.")
        group.add_argument("--end", metavar="X,Y,Z",
                           help="odmo: make the root trajectory end at this location.")
        group.add_argument("--list-modes", action="store_true",
                           help="odmo: print the modes found per action with their sizes, and exit.")

    def handle(self, *args, **options):
        source = options["source"]
        if options["n"] < 1:
            raise CommandError(f"--n must be at least 1; got {options['n']}")
        if options["list_modes"]:
            return self._list_modes(source, options)
        if not options["out"]:
            raise CommandError("--out FILE.npz is required")
        try:
            if source == REAL:
                motions = self._real(options)
            else:
                motions = self._generated(source, options)
            path = npz.save(options["out"], motions)
        except (DatasetError, MethodError, CheckpointError, SamplingError, npz.FormatError) as exc:
            raise CommandError(str(exc)) from None
        actions = sorted({m.action for m in motions})
        self.stdout.write(
            f"wrote {len(motions)} {source} motions ({', '.join(actions)}) to {path}"
        )

    def _list_modes(self, source, options):
        if not options["checkpoint"]:
            raise CommandError("--list-modes needs --checkpoint FILE of a method with modes (odmo)")
        try:
            model = get_method(source).load(options["checkpoint"])
            actions = choose(options["action"], model.actions, "action",
                             f"checkpoint {options['checkpoint']}")
            modes = model.modes() if hasattr(model, "modes") else None
        except KeyError as exc:
            raise CommandError(exc.args[0]) from None
        except (MethodError, CheckpointError, SamplingError) as exc:
            raise CommandError(str(exc)) from None
        if modes is None:
            raise CommandError(f"{source} has no modes; --list-modes is for odmo and odmo_conv")
        for action in actions:
            found = ", ".join(f"mode {m['mode']}: {m['size']} clips ({m['weight']:.0%})"
                              for m in modes[action])
            self.stdout.write(f"{action}: {len(modes[action])} modes; {found or 'no training clips'}")

    def _real(self, options):
        if not options["dataset"]:
            raise CommandError("source 'real' needs --dataset NAME")
        try:
            dataset = get_dataset(options["dataset"], options["data_root"])
        except KeyError as exc:
            raise CommandError(exc.args[0]) from None
        return sample_real(dataset, options["action"], options["n"], frames=options["frames"],
                           seed=options["seed"], fps=options["fps"], subjects=options["subjects"])

    def _generated(self, source, options):
        try:
            get_method(source)
        except KeyError:
            raise CommandError(
                f"unknown source {source!r}; choose '{REAL}' or one of: {', '.join(list_methods())}"
            ) from None
        if not options["checkpoint"]:
            raise CommandError(f"source {source!r} needs --checkpoint FILE (written by `train`)")
        return sample_method(options["checkpoint"], options["action"], options["n"],
                             frames=options["frames"], seed=options["seed"], method=source,
                             **method_options(options))


def method_options(options: dict) -> dict:
    """Return the method-specific sampling options given on the command line."""
    chosen = {}
    if options["bone_lengths_from"]:
        motions = npz.load(options["bone_lengths_from"])
        lengths = np.stack([get_skeleton(m.skeleton).bone_lengths(m.joints) for m in motions])
        chosen["bone_lengths"] = np.median(lengths.reshape(-1, lengths.shape[-1]), axis=0)
    if options["mix"]:
        chosen["mix"] = parse_weights(options["mix"])
    if options["mode"] is not None:
        chosen["mode"] = options["mode"]
    if options["interpolate"]:
        chosen["interpolate"] = tuple(parse_numbers(options["interpolate"], "--interpolate", 2, int))
    if options["end"]:
        chosen["end"] = parse_numbers(options["end"], "--end", None, float)
    return chosen


def parse_weights(text: str) -> dict[str, float]:
    """Parse ``A=0.5,B=0.5`` into ``{"A": 0.5, "B": 0.5}``."""
    weights = {}
    for part in text.split(","):
        name, _, value = part.partition("=")
        try:
            weights[name.strip()] = float(value)
        except ValueError:
            raise CommandError(f"--mix {text!r}: write ACTION=WEIGHT pairs, e.g. Walking=0.5,Phoning=0.5") from None
    return weights


def parse_numbers(text: str, flag: str, count: int | None, kind) -> list:
    """Parse comma-separated numbers of a flag, checking how many there are."""
    try:
        values = [kind(part) for part in text.split(",")]
    except ValueError:
        raise CommandError(f"{flag} {text!r}: expected comma-separated numbers") from None
    if count is not None and len(values) != count:
        raise CommandError(f"{flag} {text!r}: expected {count} numbers")
    return values

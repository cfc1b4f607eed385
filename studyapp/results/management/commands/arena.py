from django.core.management.base import BaseCommand, CommandError

from studyapp.results import arena, leaderboard
from studyapp.results.audit import LEVELS
from studyapp.stimuli.build import BuildError
from studyapp.stimuli.config import ConfigError


class Command(BaseCommand):
    help = (
        "A standing study of sources judged in pairs (study.arena in its config): add a "
        "source from a results file (imported, checked to cover every prompt, rendered as "
        "the arena's clips, audited for blindness, registered), retire one (never shown "
        "again; its answers and scores kept), compute the public leaderboard "
        "(/arena/<slug>/), or list the arena's prompts."
    )

    def add_arguments(self, parser):
        commands = parser.add_subparsers(dest="action", required=True)
        add = commands.add_parser("add", help="Add a source to an arena.")
        add.add_argument("--study", required=True, metavar="SLUG")
        add.add_argument("--file", required=True,
                         help="The source's motions, e.g. MDM's results.npy (any format "
                              "import_motions reads), one or more of every prompt.")
        add.add_argument("--name", required=True, help="The source's name on the leaderboard.")
        add.add_argument("--format", default="auto", help="The file's format (default: auto).")
        add.add_argument("--out", help="The arena's build folder (default: <var>/stimuli/<slug>).")
        add.add_argument("--cache", help="The build's cache (default: as build_stimuli's).")
        add.add_argument("--audit", choices=[*LEVELS, "none"], default="deep",
                         help="The blindness audit run with the new clips (default: deep).")
        retire = commands.add_parser("retire", help="Stop showing a source; keep its history.")
        retire.add_argument("--study", required=True, metavar="SLUG")
        retire.add_argument("--name", required=True)
        board = commands.add_parser("board", help="Compute the leaderboard now and store it.")
        board.add_argument("--study", required=True, metavar="SLUG")
        board.add_argument("--bootstrap", type=int, default=leaderboard.BOOTSTRAP,
                           help=f"Bootstrap replicates (default: {leaderboard.BOOTSTRAP}).")
        prompts = commands.add_parser("prompts", help="Print the arena's prompts, one a line.")
        prompts.add_argument("--study", required=True, metavar="SLUG")

    def handle(self, *args, action, study, **options):
        try:
            record = arena.arena_of(study)
            if action == "add":
                done = arena.add(record, options["file"], options["name"], options["format"],
                                 options["out"], options["cache"],
                                 None if options["audit"] == "none" else options["audit"],
                                 log=self.stdout.write)
                audit = ("not run" if done["audit"] is None else
                         "passed: " + "; ".join(p["says"] for p in done["audit"].values()))
                self.stdout.write(
                    f"arena {record.slug}: added {done['source']} ({done['judged']} clips of "
                    f"{done['prompts']} prompts, {done['clips'] - done['judged']} catch clips; "
                    f"{done['rendered']} rendered now); blindness audit {audit}; the adaptive "
                    f"design now aims at it")
            elif action == "retire":
                arena.retire(record, options["name"])
                self.stdout.write(f"arena {record.slug}: {options['name']} retired; its answers "
                                  f"and scores stay on the leaderboard, marked retired")
            elif action == "board":
                board = leaderboard.compute(record, options["bootstrap"])
                for row in board["sources"]:
                    score = "-" if row["score"] is None else f"{row['score']:.2f}"
                    if row["ci_low"] is not None and row["ci_high"] is not None:
                        score += f" [{row['ci_low']:.2f}, {row['ci_high']:.2f}]"
                    marks = [m for m, on in (("preliminary", row["preliminary"]),
                                             (f"anchor: {row['anchor']}", row["anchor"]),
                                             ("retired", row["retired"])) if on]
                    self.stdout.write(f"{row['rank'] or '-':>3} {row['source']:<24} {score:<24} "
                                      f"{row['votes']:>6} votes  {', '.join(marks)}")
            else:
                for prompt in arena.prompts_of(record):
                    self.stdout.write(prompt)
        except (arena.ArenaError, ConfigError, BuildError) as exc:
            raise CommandError(str(exc)) from None

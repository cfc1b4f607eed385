"""Render interchange .npz files to study videos: ``manage.py render FILE.npz --out DIR``.

``--grid PATH`` also (or only) writes every clip into one labelled grid video and a
contact sheet, for papers and the admin.
"""

from pathlib import Path

from django.core.management.base import BaseCommand, CommandError

from motion.formats import npz
from rendering import FORMATS, list_styles, render_grid, render_set

GRID_WARNING = 36  # more cells than this make a grid too small to read


class Command(BaseCommand):
    help = (
        "Render the motions of interchange .npz files to mp4 videos and PNG posters named "
        "by content hash, with renders.json (the researcher's record) beside them. Give "
        "every source of a study in one call: the clips then share one framing. "
        "--formats mp4,webm,gif adds VP9 WebM and GIF copies beside each mp4 (the mp4 is "
        "always written). --grid PATH writes all clips into one labelled grid video (PATH, "
        ".mp4) and a contact sheet (PATH with .png), labelled by source and action: for "
        "papers and the admin, never for participants; with --grid, --out is optional."
    )

    def add_arguments(self, parser):
        parser.add_argument("files", nargs="+", type=Path, metavar="FILE.npz")
        parser.add_argument("--out", type=Path, help="folder for the clips")
        parser.add_argument("--style", default="stick", choices=list_styles())
        parser.add_argument("--size", type=int, default=480, help="width = height, even")
        parser.add_argument("--fps", type=float, help="resample every clip to this rate")
        parser.add_argument("--workers", type=int, default=1, help="rendering processes")
        parser.add_argument(
            "--still-camera", action="store_true",
            help="keep the camera still instead of following each root sideways",
        )
        parser.add_argument(
            "--formats", default="mp4", metavar="LIST",
            help=f"comma-separated video formats from {','.join(FORMATS)} (mp4 always)",
        )
        parser.add_argument("--grid", type=Path, metavar="PATH.mp4",
                            help="also write a labelled grid video and contact sheet")
        parser.add_argument("--grid-size", type=int, default=240, help="grid cell size, even")

    def handle(self, *args, **options):
        size, fps, workers = options["size"], options["fps"], options["workers"]
        if size <= 0 or size % 2:
            raise CommandError(f"--size must be a positive even number; got {size}")
        if fps is not None and fps <= 0:
            raise CommandError(f"--fps must be positive; got {fps}")
        if workers < 1:
            raise CommandError(f"--workers must be at least 1; got {workers}")
        if options["out"] is None and options["grid"] is None:
            raise CommandError("give --out (a folder for the clips), --grid PATH.mp4, or both")
        requested = [f.strip().lower() for f in options["formats"].split(",") if f.strip()]
        formats = ["mp4"] + [f for f in dict.fromkeys(requested) if f != "mp4"]
        unknown = sorted(set(formats) - set(FORMATS))
        if unknown:
            raise CommandError(f"unknown --formats {unknown}; choose from {','.join(FORMATS)}")
        grid, grid_size = options["grid"], options["grid_size"]
        if grid is not None and grid.suffix.lower() != ".mp4":
            raise CommandError(f"--grid must name an .mp4 file; got {grid}")
        if grid_size <= 0 or grid_size % 2:
            raise CommandError(f"--grid-size must be a positive even number; got {grid_size}")
        motions = []
        for path in options["files"]:
            try:
                motions.extend(npz.load(path))
            except npz.FormatError as exc:
                raise CommandError(str(exc)) from None
        rates = sorted({m.fps for m in motions})
        if fps is None and len(rates) > 1:
            self.stderr.write(f"warning: the clips' frame rates differ {rates}; pass --fps")

        if options["out"] is not None:
            self._render_clips(motions, options, size, fps, workers, formats)
        if grid is not None:
            self._render_grid(motions, options, grid, grid_size, fps)

    def _render_clips(self, motions, options, size, fps, workers, formats):
        report = render_set(
            motions,
            options["out"],
            style=options["style"],
            size=size,
            fps=fps,
            workers=workers,
            progress=options["verbosity"] > 0,
            follow=not options["still_camera"],
            formats=formats,
        )
        self.stdout.write(
            f"rendered {len(report.clips)} of {len(motions)} clips "
            f"({options['style']}, {size}x{size}, {'/'.join(formats)}) to {options['out']}"
        )
        if report.sidecar:
            self.stdout.write(f"record: {report.sidecar}")
        for index, message in report.failures:
            motion = motions[index]
            self.stderr.write(f"failed: clip {index} ({motion.action}, {motion.source}): {message}")
        if not report.clips:
            raise CommandError("no clip was rendered")

    def _render_grid(self, motions, options, path, size, fps):
        if len(motions) > GRID_WARNING:
            self.stderr.write(f"warning: a grid of {len(motions)} clips is hard to read")
        try:
            grid = render_grid(motions, None, path, style=options["style"], size=size, fps=fps)
        except ValueError as exc:  # RenderError included: a clip the style cannot draw
            raise CommandError(f"cannot render the grid: {exc}") from None
        self.stdout.write(f"grid of {len(motions)} clips: {grid.video} and {grid.sheet}")

"""Write a contact sheet of every clip under a folder (a render output or a stimulus build).

    .venv/bin/python scripts/contact_sheet.py var/stimuli docs/images/demo_contact_sheet.jpg

Labels come from the folder's ``renders.json`` / ``manifest.json`` records and name the
sources: the sheet is for researchers, never for participants.
"""

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rendering.sheet import find_clips, write_sheet  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path, help="a folder of clips, searched recursively")
    parser.add_argument("out", type=Path, help="the sheet: .png or .jpg")
    parser.add_argument("--moments", type=int, default=4, help="frames shown per clip")
    parser.add_argument("--size", type=int, default=96, help="pixels per frame")
    parser.add_argument("--columns", type=int, default=3, help="clips side by side")
    parser.add_argument("--cache", type=Path, help="a stimulus build's cache, if not the "
                        "default one beside its folder (<var>/stimuli/cache)")
    options = parser.parse_args()
    if not options.folder.is_dir():
        parser.error(f"{options.folder} is not a folder")
    try:
        count = len(find_clips(options.folder, options.cache))
    except FileNotFoundError as exc:
        parser.error(str(exc))
    if not count:
        parser.error(f"no mp4 clips under {options.folder} (nor, for a stimulus build's "
                     f"folder, in its cache: pass --cache)")
    path = write_sheet(options.folder, options.out, options.moments, options.size,
                       options.columns, options.cache)
    print(f"contact sheet of {count} clips: {path}")


if __name__ == "__main__":
    main()

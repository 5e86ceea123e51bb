"""Entry point for ``python -m headless`` and for ``blender --python headless/__main__.py``."""

import sys
from pathlib import Path

if __package__ in (None, ""):
    # Run as a script (inside a Blender binary): make the repository importable.
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from headless.cli import main  # noqa: E402


def _arguments() -> list[str]:
    """Our arguments: everything after ``--`` when Blender passed its own first."""
    argv = sys.argv[1:]
    return argv[argv.index("--") + 1 :] if "--" in argv else argv


if __name__ == "__main__":
    sys.exit(main(_arguments()))

"""Entry point for ``python -m headless`` and for ``blender --python headless/__main__.py``."""

import sys
from pathlib import Path

if __package__ in (None, ""):
    # Run as a script (inside a Blender binary): make the repository importable.
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def _arguments() -> list[str]:
    """Our arguments: everything after ``--`` when Blender passed its own first."""
    argv = sys.argv[1:]
    return argv[argv.index("--") + 1 :] if "--" in argv else argv


# (Worker processes import this module again, as ``__mp_main__``: they run none of it.)
if __name__ == "__main__":
    # First of all: from here on Ctrl-C and SIGTERM end the run cleanly.
    from headless import interrupts

    interrupts.install()
    try:  # (numpy and the rest load here: a second or more)
        from headless.cli import main
    except KeyboardInterrupt:
        interrupts.last_line()
        sys.exit(interrupts.EXIT_INTERRUPTED)
    sys.exit(interrupts.finish(main(_arguments())))

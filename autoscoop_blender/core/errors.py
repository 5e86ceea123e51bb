"""Typed errors for user mistakes: bad scenes, bad settings, bad files.

Each message is one line that names the object and the problem, so the CLI prints it
as it is (exit code 2) and the Blender operator passes it to ``self.report``.
"""


class AutoscoopError(Exception):
    """A mistake in what the user gave us, not a bug: message names object and fault."""


class SceneContractError(AutoscoopError):
    """The scene does not follow the contract (areas, curves, occluders)."""


class InputError(AutoscoopError):
    """A settings or sensors file, or a command-line value, is unusable."""

"""AutoSCOOP: road-side sensor placement for vehicle proving grounds.

``register()``/``unregister()`` only; submodules are imported lazily so that the
Blender-free ``core`` package can be used (and tested) without bpy.
"""

import importlib

# Blender glue modules, registered in this order and unregistered in reverse.
_GLUE_MODULES: tuple[str, ...] = ("props", "ops", "import_ops", "ui", "scene.live")


def register() -> None:
    for name in _GLUE_MODULES:
        importlib.import_module(f"{__package__}.{name}").register()


def unregister() -> None:
    for name in reversed(_GLUE_MODULES):
        importlib.import_module(f"{__package__}.{name}").unregister()

"""ASAM OpenDRIVE (.xodr) import, Blender-free: parse a file, then build road meshes,
target rings (chosen lane types) and sensor-area bands for a scene.

The reader and the geometry are written here rather than taken from a library:
``pyxodr-omega-prime`` runs on Python 3.11 but ignores superelevation, ``pyopendrive``
needs Python >= 3.12 (Blender 4.2 to 5.0 ship 3.11) and libOpenDRIVE is C++ (a
compiled module per platform and Python). What the import needs of the standard is
small: five reference-line kinds, cubic profiles and lane borders, evaluated with
numpy and ``scipy.special.fresnel`` and tested against closed forms
(tests/core/test_opendrive*.py). ``geometry`` says what is modelled and what is not,
``build`` the sampling rule.

    network = read_opendrive("track.xodr")        # InputError if not usable at all
    result = build_import(network, ("driving",), band=(1.0, 6.0), terrain="flat")
"""

from .build import (
    LANE_TYPES,
    AreaRings,
    ImportedNetwork,
    SurfaceMesh,
    build_import,
)
from .parse import OpenDriveNetwork, read_opendrive

__all__ = [
    "LANE_TYPES",
    "AreaRings",
    "ImportedNetwork",
    "OpenDriveNetwork",
    "SurfaceMesh",
    "build_import",
    "read_opendrive",
]

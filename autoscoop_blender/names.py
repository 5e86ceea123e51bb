"""Names shared by the whole extension: object-name prefixes, custom properties, idnames.

The scene contract lives here and nowhere else: a curve whose name starts with
``Target`` is a target area, one whose name starts with ``SensorArea`` is a sensor
area (both case-insensitive, ``Sensor_Area`` and ``Sensor-Area`` too), one whose name
starts with ``NoMast`` cuts a hole in the sensor areas, and every other visible mesh
occludes. The panel can mark curves explicitly through ``ROLE_PROP``.
"""

import re

# Object-name prefixes of the scene contract, matched case-insensitively.
TARGET_RE = re.compile(r"^target", re.IGNORECASE)
SENSOR_AREA_RE = re.compile(r"^sensor[ _-]?area", re.IGNORECASE)
NO_MAST_RE = re.compile(r"^no[ _-]?mast", re.IGNORECASE)

# Custom properties a user (or the panel) may set on objects.
ROLE_PROP = "autoscoop_role"  # marks an object explicitly, whatever its name
ROLE_TARGET = "target"  # a curve: target area
ROLE_SENSOR_AREA = "sensor_area"  # a curve: sensor area
ROLE_NO_MAST = "no_mast"  # a curve: a hole in the sensor areas (escape lane, pipeline)
ROLE_SENSOR = "sensor"  # a camera: a sensor to evaluate
ROLE_MAST = "mast"  # an empty: a mast that stands already, with free slots
ROLE_NONE = "none"  # unmarked: not an area even if the name says so
IGNORE_PROP = "autoscoop_ignore"  # True: the mesh does not occlude
OVERHANG_PROP = "autoscoop_overhang"  # True: occludes, but nothing stands on it
MOUNT_PROP = "autoscoop_mount"  # True: masts may stand on its top (roof, gantry, deck)
HEIGHT_PROP = "height_m"  # on a sensor area: mast height there, metres
# On a target area: what its points require (issue 16's planners' requirements).
COVERAGE_K_PROP = "coverage_k"  # int >= 1: sensors that must see each point
DORI_PROP = "dori"  # "detect", "observe", "recognise" or "identify": camera px/m
REQUIRE_PROP = "require"  # a sensor kind ("camera", "lidar", "radar") that must see it

# Georeference, on the Blender scene (set by the OpenDRIVE import, or by hand): the
# projected CRS of the scene's world metres, and where the scene sits in it. A scene
# point p is at (cos h * px - sin h * py + x, sin h * px + cos h * py + y, pz + z) in
# the CRS, with CRS_OFFSET_PROP = (x, y, z, h); h in radians (OpenDRIVE's header
# <offset> convention, with any shift the import made to keep coordinates small).
CRS_PROP = "autoscoop_crs"  # a PROJ string, "EPSG:nnnn" or WKT
CRS_OFFSET_PROP = "autoscoop_crs_offset"  # (x, y, z, hdg): metres, metres, metres, rad
# On objects made by the OpenDRIVE import: where they came from.
XODR_ROAD_PROP = "autoscoop_xodr_road"  # the road id (a string, as in the file)
XODR_LANES_PROP = "autoscoop_xodr_lanes"  # the lane type(s), e.g. "driving"
# On the scene: an OpenDRIVE header's geoReference that PROJ cannot read (kept as
# given, for the record; the scene then has no CRS).
XODR_GEOREF_PROP = "autoscoop_xodr_georeference"

# Everything AutoSCOOP creates goes into this collection and nowhere else.
RESULTS_COLLECTION = "AutoSCOOP Results"
RESULTS_TAG = "autoscoop_results"  # set on it, so it is found if Blender renames it

# Operator idnames (bpy.ops.autoscoop.*) and the panel's category.
OP_OPTIMIZE = "autoscoop.optimize"
OP_EVALUATE = "autoscoop.evaluate"
OP_MARK = "autoscoop.mark"
OP_CHECK = "autoscoop.check"
OP_EXPORT = "autoscoop.export"
OP_CLEAR = "autoscoop.clear_results"
OP_SNAP = "autoscoop.snap_to_mast"
OP_FILL = "autoscoop.fill_gap"
OP_REPLAN = "autoscoop.replan_rest"
OP_IMPORT_XODR = "autoscoop.import_xodr"
PANEL_CATEGORY = "AutoSCOOP"

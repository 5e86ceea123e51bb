"""What each key of result.json and each column of sensors.csv means, once: the
reference page (``docs/reference/results.md``) is generated from these tables, and a
test checks that a real run's files hold exactly these keys.

Each table maps a key to (type, meaning). Lengths in metres, angles in degrees, areas
in m^2, positions in the scene's world frame (x east, y north, z up) unless said.
"""

from __future__ import annotations

Fields = dict[str, tuple[str, str]]

RESULT: Fields = {
    "schema": ("string", 'the file\'s format, "autoscoop.result/1"'),
    "scene": ("string", "the .blend file planned"),
    "targets_fingerprint": (
        "string",
        "a hash of each target area's name, plan area and bounds: which ground the plan "
        "is for (``--existing`` warns when it differs)",
    ),
    "optimizer": ("string", "lp, greedy or es"),
    "method": ("string", "the coverage method: targeted or pointcloud"),
    "seed": ("integer", "the random seed (the es's; lp and greedy draw nothing at random)"),
    "settings": ("object", "every setting of the run, as in the config file"),
    "model": (
        "object",
        "the sensor model (every key of a model); with ``sensors`` it is a sensors file "
        "that ``headless coverage`` reads",
    ),
    "models": (
        "list",
        "mixed packs only: each model with its ``sensor_cost``",
    ),
    "versions": ("object", "AutoSCOOP, Python, numpy, scipy, shapely and Blender versions"),
    "metrics": ("object", "the plan's figures: see the metrics table"),
    "stop_reason": ("string", "why the run ended, in words"),
    "interrupted": (
        "boolean",
        "true when Ctrl-C, SIGTERM or Esc stopped the run early: the best plan by then",
    ),
    "notes": (
        "list",
        "what a reader of the plan should know about the scene, e.g. that nothing in it "
        "stands up from the ground, so sight lines were clear but for the terrain (an "
        "OpenDRIVE import)",
    ),
    "uncovered": (
        "list",
        "uncovered patches, largest first: ``target`` (area name), ``m2``, centroid ``x``, ``y``",
    ),
    "no_mast_sites": (
        "list",
        "pieces of sensor areas where no mast may stand: ``area``, ``cause`` (the "
        "object standing there or the no-mast zone), ``m2``",
    ),
    "sensors": ("list", "one object per sensor: see the sensors table"),
    "masts": ("list", "one object per mast: see the masts table"),
    "origin": (
        "list",
        "the local origin the scene was moved to before rays were cast (zero unless it "
        "lies far from the origin); every output is in the scene's own frame",
    ),
}

METRICS: Fields = {
    "coverage_fraction": ("number", "share of the target points covered, each to its k"),
    "covered_m2": ("number", "the target area covered, each point to its k"),
    "coverage_k": ("integer", "the k of the settings (sensors a point needs)"),
    "coverage_k_max": ("integer", "the largest k of any target area"),
    "coverage_by_k": (
        "object",
        "for k = 1, 2, 3: the ``fraction`` and ``m2`` covered by at least k sensors",
    ),
    "target_area_m2": ("number", "the target points times a grid cell's area"),
    "sensors": ("integer", "sensors in the plan"),
    "masts": ("integer", "masts in the plan"),
    "cluster_ratio": ("number", "masts / sensors (the paper's)"),
    "relative_sensor_coverage": (
        "number",
        "mean footprint per sensor / the model's largest flat-ground footprint (the "
        "paper's; null when no flat ground meets the model's threshold)",
    ),
    "reference_footprint_m2": ("number", "that largest flat-ground footprint"),
    "overlap_factor": (
        "number",
        "the sensors' covered target m^2 summed / the target m^2 (the paper's)",
    ),
    "mean_epochs_per_sensor": (
        "number",
        "es only: ES epochs per sensor (the paper's); 0 for lp and greedy, which run no epochs",
    ),
    "evaluations": ("integer", "sensor poses whose coverage was computed"),
    "wall_s": ("number", "seconds the optimization took (not loading or writing)"),
    "rays_cast": ("integer", "rays cast through the scene"),
    "cost": ("number", "mast_cost x new masts + each new sensor's cost"),
    "objective": ("number", "the value of the objective: cost, sensors or masts"),
    "lower_bound": (
        "number",
        "no plan on the candidate set (``bound_scope``) has a lower objective; null "
        "without a bound (es and greedy without ``--bound``)",
    ),
    "gap": ("number", "(objective - lower_bound) / objective; 0 means proven optimal"),
    "sensors_lower_bound": ("integer", "no plan has fewer sensors"),
    "masts_lower_bound": ("integer", "no plan has fewer masts"),
    "sensors_on_masts_lower_bound": (
        "integer",
        "no plan whose new sensors stand on this plan's masts (or on masts that stood "
        "already) has fewer new sensors: when it equals the plan's, a plan with fewer "
        "needs other masts; null when not proven (a plan proven optimal, a run stopped or out "
        "of time first, a ground in parts re-planned by windows)",
    ),
    "joint_lower_bound": (
        "number",
        "cost: no plan costs less, from masts and sensors together (the fewest sensors "
        "any plan on m masts needs, for every m; planned in parts, the parts' bounds "
        "on both at one split of the goal); null when not proven",
    ),
    "lp_bound": ("number", "the LP's bound on the sensors' cost before rounding up"),
    "lp_rounds": ("integer", "column generation rounds of the LP"),
    "bound_scope": (
        "string",
        "which plans the bound is about: the mast lattice, orientations and grid, and "
        "the parts it was proven in",
    ),
    "existing_sensors": ("integer", "sensors that stood already (``--existing``)"),
    "existing_masts": ("integer", "masts that stood already"),
}

SENSOR: Fields = {
    "n": ("integer", "1-based number, in the order the sensors were fixed"),
    "x": ("number", "position of the mast, east"),
    "y": ("number", "position of the mast, north"),
    "z": ("number", "height of the sensor, absolute"),
    "height_m": ("number", "height of the sensor above the ground under its mast"),
    "pitch_deg": ("number", "depression below the horizon: positive looks down"),
    "yaw_deg": ("number", "view direction, counter-clockwise from +x (east), [0, 360)"),
    "mast": ("integer", "the mast it is on (``masts[].n``)"),
    "fitness": (
        "number",
        "es: the paper's fitness (Eq. 5) when it was fixed; lp and greedy: the target "
        "points it raised towards their k when it was fixed",
    ),
    "epochs": ("integer", "es: ES epochs it took; 0 for lp and greedy"),
    "target_covered_m2": ("number", "target area it covers on its own"),
    "footprint_m2": ("number", "its whole footprint on the ground, targets or not"),
    "existing": ("boolean", "true when it stood already (``--existing``)"),
    "model": ("object", "mixed packs only: its model"),
}

MAST: Fields = {
    "n": ("integer", "1-based number"),
    "x": ("number", "position, east"),
    "y": ("number", "position, north"),
    "z_ground": ("number", "height of the ground at its foot, absolute"),
    "height_m": ("number", "height of its (first) sensor above the ground"),
    "sensors": ("list", "the sensors on it (``sensors[].n``)"),
    "existing": ("boolean", "true when it stood already"),
}

SENSORS_CSV: Fields = {
    "n": ("integer", "as in result.json"),
    **{k: SENSOR[k] for k in ("x", "y", "z", "height_m", "pitch_deg", "yaw_deg")},
    "bearing_deg": (
        "number",
        "the same direction as a compass bearing: clockwise from the scene's +y (grid "
        "north; ``sensors.geojson`` gives it from true north when the scene has a CRS)",
    ),
    "fitness": ("number", "as in result.json"),
    "target_covered_m2": SENSOR["target_covered_m2"],
    "mast": ("integer", "the mast it is on, as in result.json"),
    "existing": ("integer", "1 when it stood already, else 0"),
    "kind": ("string", "camera, lidar or radar"),
}

# The tables in the order the reference shows them: (title, fields).
TABLES: tuple[tuple[str, Fields], ...] = (
    ("result.json", RESULT),
    ("result.json: metrics", METRICS),
    ("result.json: sensors[]", SENSOR),
    ("result.json: masts[]", MAST),
    ("sensors.csv", SENSORS_CSV),
)

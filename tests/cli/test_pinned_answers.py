"""The answers users get today, pinned pose for pose.

``tests/data/two_routes_*.json`` hold what ``headless optimize`` gives on the bundled
``two_routes`` scene: the paper's ES with seed 0 (65 sensors on 57 masts, 97.11 %) and
greedy (45 sensors on 18 masts, 97.12 %). First pinned before the core was reshaped
into stages (commit cac9cc0; 64 on 56 and 40 on 24); re-pinned at f3abf1a, when
occluders came to be cropped by their exact distance: two faces 79.98 m from a sensor
area, which the bounding-box crop had dropped, now stay and change a footprint by
1 m^2 and, through it, the ES's path; greedy re-pinned when its mast preference for
the cost objective became 1 (``bench constants``; 40 on 24, 97.04 %, at 0.1), and
again when candidates dominated by another at the same position and model came to be
left out: three of its tied choices turn 10 degrees to the dominating yaw (same 45 on
18, 97.12 %). A change that alters any pose, mast or covered
point fails here; one that means to change them must say so and regenerate the files.
"""

import json

import pytest

from tests.cli.conftest import SAMPLES, run_headless
from tests.conftest import ROOT

POSE_KEYS = ("x", "y", "z", "height_m", "pitch_deg", "yaw_deg", "mast")
METRIC_KEYS = (
    "coverage_fraction",
    "covered_m2",
    "target_area_m2",
    "sensors",
    "masts",
    "cluster_ratio",
    "relative_sensor_coverage",
    "overlap_factor",
    "mean_epochs_per_sensor",
    "evaluations",
)


@pytest.mark.parametrize(
    ("pinned", "args"),
    [
        ("two_routes_es_seed0", ("--optimizer", "es", "--seed", "0")),
        ("two_routes_greedy", ("--optimizer", "greedy")),
    ],
)
def test_two_routes_gives_the_pinned_layout(tmp_path, pinned, args):
    expected = json.loads((ROOT / "tests" / "data" / f"{pinned}.json").read_text())
    code, _, stderr = run_headless(
        "optimize", SAMPLES / "two_routes.blend", *args, "--out-dir", tmp_path
    )
    assert code == 0, stderr
    got = json.loads((tmp_path / "result.json").read_text())
    assert len(got["sensors"]) == len(expected["sensors"])
    for mine, theirs in zip(got["sensors"], expected["sensors"]):
        assert {k: mine[k] for k in POSE_KEYS} == {k: theirs[k] for k in POSE_KEYS}
        assert mine["target_covered_m2"] == theirs["target_covered_m2"]
        assert mine["footprint_m2"] == theirs["footprint_m2"]
    assert got["masts"] == expected["masts"]
    assert {k: got["metrics"][k] for k in METRIC_KEYS} == expected["metrics"]

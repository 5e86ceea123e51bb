"""Sensor models and poses: field of view, ray pattern, analytic point density, presets.

Frames and units
----------------
World (local) metres, Z up. A pose stands at ``(x, y)`` with the optical centre at
absolute height ``z`` (ground under the mast + ``height_m``). ``yaw_deg`` is the heading
counter-clockwise from +X, ``pitch_deg`` the depression below the horizon (positive
looks down), roll is 0. The sensor frame has three unit axes, stacked as the rows of
``frame(pitch, yaw)``: ``forward`` (optical axis), ``left`` and ``up``, with
``forward x left = up``.

Ray patterns
------------
``angular``: rays spaced evenly in azimuth ``a`` (about ``up``) and elevation ``b``
(from the forward/left plane), one ray in the centre of each angular cell; this is
what a spinning lidar or a game-engine ray-cast sensor does. ``pinhole``: rays through
the centres of an even grid on a flat image plane, as in a real camera.

Point density
-------------
All densities are points per m^2 of the *XY projection* (the paper projects the point
cloud to the ground plane), in the units of the sensor's own pattern of
``rays_h x rays_v`` points. A surface point at distance ``r`` along unit direction
``d`` with unit normal ``n`` receives

    rho_xy = rho_sr(d) * |d . n| / (r^2 * |n_z|)

points per m^2, where ``rho_sr`` is the pattern's rays per steradian:
``N / (H * V * cos b)`` for ``angular`` (H, V the FoV in radians) and
``N / (W * T * cos^3 t)`` for ``pinhole`` (W, T the image plane's width and height at
focal length 1, ``t`` the angle off the optical axis).

Pixel density (DORI)
--------------------
A ``camera`` with ``pattern = "pinhole"`` may give its image ``resolution_px = (w, h)``
and a required pixel density ``min_px_per_m`` (a number or a level of
``DORI_PX_PER_M``: EN 62676-4's detect 25, observe 62, recognise 125, identify 250 px/m).
Its focal lengths in pixels are ``f_x = (w / 2) / tan(H / 2)`` and
``f_y = (h / 2) / tan(V / 2)`` (H, V the FoV; square pixels, ``f_x = f_y``, are
required within 2 %). A patch of surface at distance ``r`` along unit direction ``d``
with unit normal ``n`` spans the solid angle ``|d . n| / r^2`` per m^2; a solid angle
at angle ``t`` off the optical axis spans ``1 / cos^3 t`` of image plane at focal
length 1, which holds ``f_x f_y`` pixels per unit. So the surface receives

    P = f_x * f_y * |d . n| / (r^2 * cos^3 t)        pixels per m^2 of surface

(the pinhole pattern's density above with ``rays = w x h``, on the surface itself
rather than its XY projection), and the pixel density at the point is

    px_per_m = sqrt(P) = sqrt(f_x f_y |d . n| / (r^2 cos^3 t)).

Why the geometric mean of the two directions on the surface (sqrt of pixels per m^2)
and not the worse of the two: it is the px/m of a square of surface holding the same
number of pixels, which is what recognising a thing of a given size needs; it does not
depend on how that thing is turned within the surface; it equals the CCTV figure
``f / depth`` (EN 62676-4, the calculators) for a surface facing the camera, anywhere
in the image; and it follows the same law as the density of the pinhole pattern, so the
test is as exact and cheap as that one. The worse direction would fall to 0 at grazing
incidence and make the level depend on the heading of the target. On flat ground,
for a camera ``h`` above it, ``|d . n| = h / r`` and ``r cos t = D`` (the depth along
the optical axis), so ``px_per_m = sqrt(f_x f_y h / D^3)``: a level is reached up to
the depth ``D = (f_x f_y h / px^2)^(1/3)``, a straight line across the ground footprint.

A point counts for such a camera when it is in line of sight, range and FoV, the
pattern's density reaches ``min_density_per_m2`` (0 in ``cctv_camera``) and
``px_per_m`` reaches the larger of the model's ``min_px_per_m`` and its target area's
``dori``. A model without a resolution (every lidar, radar and angular camera) cannot
cover a point whose target area asks for a DORI level.

One module of about 700 lines: a sensor is one definition (its keys and limits, the
presets and packs, its ray pattern and the analytic density that decides what it
counts), checked as one by ``from_spec``.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..checks import brief, check_keys, number, whole_number
from ..errors import InputError

KINDS = ("camera", "lidar", "radar")
# The pixel densities of EN 62676-4's DORI levels, px per metre at the target.
DORI_PX_PER_M = {"detect": 25.0, "observe": 62.0, "recognise": 125.0, "identify": 250.0}
# Image width and height a camera model may give, px per axis: 50,000 is above any
# video or survey sensor (16K video is 15,360 wide, 150 MP sensors 14,204 x 10,652).
MAX_PX_AXIS = 50_000
# A required pixel density above a pixel per 0.1 mm asks for no surveillance task
# (identify, the highest DORI level, is 250 px/m).
MAX_PX_PER_M = 10_000.0
# Pixels are square (f_x = f_y) within this relative difference; else the FoV and the
# resolution disagree (a typo, or a FoV left from another camera).
MAX_PIXEL_ASPECT_ERR = 0.02
PATTERNS = ("angular", "pinhole")

# |n_z| below this counts as a vertical face; keeps the XY projection finite.
_MIN_NZ = 1e-3

# --- limits of what a file may ask for ------------------------------------------------
# The longest reach of any road-side sensor: long-range 77 GHz radars and lidars see
# cars to about 250-300 m, so 2 km leaves a wide margin; the Blender panel's range
# field stops there too. Beyond it the ground grid around a sensor (range^2 cells)
# would not fit in memory. A mast higher than this reaches no ground either.
MAX_RANGE_M = 2000.0
# The narrowest field of view (deg, either axis), as in the panel: a telephoto camera
# or a radar beam is still some degrees wide; below this the ray density blows up.
MIN_FOV_DEG = 0.1
# Rays per axis (the panel's limit) and per pattern: 2048 x 2048. The paper camera
# casts 30,720 rays, a 128-beam lidar 262,144; the point-cloud method holds the whole
# pattern (times its oversampling) in memory.
MAX_RAYS_AXIS = 100_000
MAX_RAYS = 2048 * 2048
# Detection thresholds above a million points per m^2 (one per mm^2) detect nothing.
MAX_DENSITY_PER_M2 = 1e6
# World coordinates (m) a sensor or a scene point may have: UTM northings reach
# 10,000 km, so any georeferenced proving ground fits; float64 keeps 2 nm there.
MAX_COORD_M = 1e7

_INTEGER_KEYS = ("rays_h", "rays_v")
_RANGE_WHY = " m (a road-side sensor's reach: the longest, radars and lidars, see about 300 m)"
# (lo, hi, unit and reason) of each numeric model key; ``validated`` adds the open
# bounds (FoV > 0, range > mount height) and the limits between keys.
_BOUNDS: dict[str, tuple[float, float, str]] = {
    "h_fov_deg": (0.0, 360.0, " deg"),
    "v_fov_deg": (0.0, 180.0, " deg"),
    "range_m": (0.0, MAX_RANGE_M, _RANGE_WHY),
    "mount_height_m": (0.0, MAX_RANGE_M, " m"),
    "pitch_min_deg": (-90.0, 90.0, " deg"),
    "pitch_max_deg": (-90.0, 90.0, " deg"),
    "rays_h": (1, MAX_RAYS_AXIS, ""),
    "rays_v": (1, MAX_RAYS_AXIS, ""),
    "min_density_per_m2": (0.0, MAX_DENSITY_PER_M2, " points per m^2"),
}


def frame(pitch_deg: float, yaw_deg: float) -> NDArray[np.float64]:
    """(3, 3) rows forward, left, up of a sensor with the given pitch and yaw (deg)."""
    p, y = math.radians(pitch_deg), math.radians(yaw_deg)
    cp, sp, cy, sy = math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    # up = forward x left, written out.
    return np.array([(cp * cy, cp * sy, -sp), (-sy, cy, 0.0), (sp * cy, sp * sy, cp)])


@dataclass(frozen=True)
class SensorPose:
    """Where a sensor stands and where it looks; local metres and degrees.

    ``z`` is absolute (ground under the mast + ``height_m``).
    """

    x: float
    y: float
    z: float
    height_m: float
    pitch_deg: float
    yaw_deg: float

    @property
    def position(self) -> NDArray[np.float64]:
        """(3,) optical centre."""
        return np.array([self.x, self.y, self.z])


@dataclass(frozen=True)
class SensorModel:
    """A ray-cast sensor: FoV (deg), range (m), mount, pitch limits, pattern, rule.

    ``min_density_per_m2`` is the detection rule: a point counts as covered when the
    sensor's pattern lands at least that many points per m^2 (XY projection) there.
    """

    kind: str
    h_fov_deg: float
    v_fov_deg: float
    range_m: float
    mount_height_m: float
    pitch_min_deg: float
    pitch_max_deg: float
    rays_h: int
    rays_v: int
    min_density_per_m2: float
    pattern: str = "angular"
    resolution_px: tuple[int, int] | None = None
    min_px_per_m: float = 0.0

    @property
    def n_rays(self) -> int:
        return self.rays_h * self.rays_v

    # --- files -------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The stable file form: the keys of the README's sensor models (kind, h_fov_deg,
        ..., min_density_per_m2, pattern), as sensors files and results write them;
        ``resolution_px`` (as a list) and ``min_px_per_m`` only for a camera with a
        resolution, so every other model writes what it always did."""
        out = asdict(self)
        if self.resolution_px is None:
            del out["resolution_px"], out["min_px_per_m"]
        else:
            out["resolution_px"] = list(self.resolution_px)
        return out

    @classmethod
    def from_spec(cls, spec: Any, label: str) -> SensorModel:
        """A model from a preset name, or a dict of keys (optionally ``preset`` + overrides).

        ``label`` names where the spec came from, for error messages.
        """
        if isinstance(spec, str):
            if spec not in PRESETS:
                close = difflib.get_close_matches(spec, sorted(PRESETS), n=1)
                hint = f"did you mean {close[0]!r}? " if close else ""
                raise InputError(
                    f"{label}: unknown sensor preset {brief(spec)} "
                    f"({hint}known: {', '.join(sorted(PRESETS))})"
                )
            return PRESETS[spec]
        if not isinstance(spec, dict):
            raise InputError(f"{label}: a model is a preset name or an object of keys")
        spec = dict(spec)
        base_name = spec.pop("preset", None)
        check_keys(spec, [f.name for f in fields(cls)] + ["preset"], label, "model")
        if base_name is not None:
            if not isinstance(base_name, str):
                raise InputError(f"{label}: preset must be a preset name, got {brief(base_name)}")
            base = cls.from_spec(base_name, label)
            model = replace(base, **spec)
        else:
            missing = sorted(
                f.name for f in fields(cls) if f.name not in spec and f.name not in _OPTIONAL
            )
            if missing:
                raise InputError(f"{label}: model misses key(s) {', '.join(missing)}")
            model = cls(**spec)
        return model.validated(label)

    def validated(self, label: str) -> SensorModel:
        """Self with numeric types normalised, or InputError naming the bad value.

        Every number must be finite and within the limits above (``MAX_RANGE_M``,
        ``MIN_FOV_DEG``, ``MAX_RAYS``, ...); ``rays_h``/``rays_v`` must be whole numbers
        (2.0 is read as 2, 1.9 is refused).
        """
        values: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ("kind", "pattern"):
                values[f.name] = v
            elif f.name == "resolution_px":
                values[f.name] = _resolution(v, label)
            elif f.name == "min_px_per_m":
                values[f.name] = _px_per_m(v, label)
            elif f.name in _INTEGER_KEYS:
                values[f.name] = whole_number(v, f.name, label, *_BOUNDS[f.name])
            else:
                values[f.name] = number(v, f.name, label, *_BOUNDS[f.name])
        m = replace(self, **values)
        if not isinstance(m.kind, str) or m.kind not in KINDS:
            raise InputError(f"{label}: kind must be one of {KINDS}, got {brief(m.kind)}")
        if not isinstance(m.pattern, str) or m.pattern not in PATTERNS:
            raise InputError(f"{label}: pattern must be one of {PATTERNS}, got {brief(m.pattern)}")
        # A flat image plane cannot reach 180 deg; a spinning pattern may go round.
        if m.pattern == "pinhole" and not 0.0 < m.h_fov_deg < 180.0:
            raise InputError(f"{label}: h_fov_deg {m.h_fov_deg} must be in (0, 180) for a pinhole")
        if m.pattern == "angular" and not 0.0 < m.h_fov_deg <= 360.0:
            raise InputError(f"{label}: h_fov_deg {m.h_fov_deg} must be in (0, 360]")
        if not 0.0 < m.v_fov_deg < 180.0:
            raise InputError(f"{label}: v_fov_deg {m.v_fov_deg} must be in (0, 180)")
        for name in ("h_fov_deg", "v_fov_deg"):
            if getattr(m, name) < MIN_FOV_DEG:
                raise InputError(
                    f"{label}: {name} {getattr(m, name):g} must be at least {MIN_FOV_DEG:g} "
                    "deg (no road-side sensor's field is narrower)"
                )
        if m.range_m <= 0:
            raise InputError(f"{label}: range_m {m.range_m} must be > 0")
        if m.range_m <= m.mount_height_m:
            raise InputError(
                f"{label}: range_m {m.range_m} does not reach the ground from the "
                f"mount height {m.mount_height_m}"
            )
        if m.pitch_min_deg > m.pitch_max_deg:
            raise InputError(
                f"{label}: pitch limits contradict: pitch_min_deg {m.pitch_min_deg} > "
                f"pitch_max_deg {m.pitch_max_deg}"
            )
        if m.n_rays > MAX_RAYS:
            raise InputError(
                f"{label}: rays_h x rays_v = {m.n_rays:,} rays must be at most {MAX_RAYS:,} "
                "(2048 x 2048; the paper camera casts 30,720)"
            )
        return m._pixels_checked(label)

    def _pixels_checked(self, label: str) -> SensorModel:
        """Self, or InputError for pixel keys on a model that cannot have them."""
        if self.resolution_px is None:
            if self.min_px_per_m > 0:
                raise InputError(
                    f"{label}: min_px_per_m {self.min_px_per_m:g} needs resolution_px "
                    "[width, height] (the pixel density follows from the image size)"
                )
            return self
        if self.kind != "camera" or self.pattern != "pinhole":
            raise InputError(
                f"{label}: resolution_px and min_px_per_m need kind camera with pattern "
                f"pinhole, got kind {self.kind} with pattern {self.pattern}"
            )
        fx, fy = self.focal_px()
        if abs(fx / fy - 1.0) > MAX_PIXEL_ASPECT_ERR:
            w, h = self.resolution_px
            v_square = math.degrees(
                2 * math.atan(h / w * math.tan(math.radians(self.h_fov_deg) / 2))
            )
            raise InputError(
                f"{label}: resolution_px {w} x {h} and h_fov_deg {self.h_fov_deg:g} give "
                f"square pixels at v_fov_deg {v_square:.2f}, not {self.v_fov_deg:g}"
            )
        return self

    # --- geometry ----------------------------------------------------------------
    def _half_fov(self) -> tuple[float, float]:
        return math.radians(self.h_fov_deg) / 2, math.radians(self.v_fov_deg) / 2

    def pattern_directions(self, oversample: int = 1) -> NDArray[np.float64]:
        """(rays_v * os, rays_h * os, 3) unit rays in the sensor frame (fwd, left, up).

        Row index runs from the top of the FoV down, column index from left to right;
        each ray sits in the centre of its pattern cell.
        """
        nh, nv = self.rays_h * oversample, self.rays_v * oversample
        ha, va = self._half_fov()
        if self.pattern == "angular":
            a = ha - (np.arange(nh) + 0.5) * (2 * ha / nh)  # left (+) to right (-)
            b = va - (np.arange(nv) + 0.5) * (2 * va / nv)  # top (+) to bottom (-)
            bb, aa = np.meshgrid(b, a, indexing="ij")
            return np.stack([np.cos(bb) * np.cos(aa), np.cos(bb) * np.sin(aa), np.sin(bb)], axis=-1)
        w, t = math.tan(ha), math.tan(va)
        u = w - (np.arange(nh) + 0.5) * (2 * w / nh)
        v = t - (np.arange(nv) + 0.5) * (2 * t / nv)
        vv, uu = np.meshgrid(v, u, indexing="ij")
        d = np.stack([np.ones_like(uu), uu, vv], axis=-1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def in_fov(self, d_sensor: NDArray[np.float64]) -> NDArray[np.bool_]:
        """(...,) whether unit directions (..., 3) in the sensor frame lie in the FoV."""
        ha, va = self._half_fov()
        fwd, left, up = d_sensor[..., 0], d_sensor[..., 1], d_sensor[..., 2]
        tol = 1e-9
        if self.pattern == "angular":
            # |elevation| <= va and |azimuth| <= ha, without the inverse trigonometry.
            ok = np.abs(up) <= math.sin(min(va + tol, math.pi / 2))
            if ha + tol >= math.pi:
                return ok
            if ha + tol >= math.pi / 2:  # wider than a half-space: exclude a back wedge
                return ok & ((fwd >= 0) | (np.abs(left) >= math.tan(math.pi - ha - tol) * -fwd))
            return ok & (fwd > 0) & (np.abs(left) <= math.tan(ha + tol) * fwd)
        with np.errstate(divide="ignore", invalid="ignore"):
            ok = fwd > 0
            su = np.abs(left) <= (math.tan(ha) + tol) * fwd
            sv = np.abs(up) <= (math.tan(va) + tol) * fwd
        return ok & su & sv

    def rays_per_sr(self, d_sensor: NDArray[np.float64]) -> NDArray[np.float64]:
        """(...,) rays per steradian of the sensor's own pattern along directions (..., 3)."""
        ha, va = self._half_fov()
        if self.pattern == "angular":
            cos_b = np.sqrt(np.clip(1.0 - d_sensor[..., 2] ** 2, 1e-12, None))
            return self.n_rays / (4 * ha * va * cos_b)
        fwd = np.clip(d_sensor[..., 0], 1e-12, None)
        return self.n_rays / (4 * math.tan(ha) * math.tan(va) * fwd**3)

    def max_rays_per_sr(self) -> float:
        """The pattern's highest rays per steradian anywhere in the FoV (at its edge)."""
        ha, va = self._half_fov()
        if self.pattern == "angular":
            return self.n_rays / (4 * ha * va * math.cos(va))
        tu, tv = math.tan(ha), math.tan(va)
        cos_corner = 1.0 / math.sqrt(1.0 + tu * tu + tv * tv)
        return self.n_rays / (4 * tu * tv * cos_corner**3)

    def max_off_axis_deg(self) -> float:
        """Largest angle between the optical axis and any direction in the FoV, deg."""
        ha, va = self._half_fov()
        if self.pattern == "angular":
            if ha >= math.pi / 2:
                return 90.0 + math.degrees(va)
            return math.degrees(math.acos(math.cos(ha) * math.cos(va)))
        tu, tv = math.tan(ha), math.tan(va)
        return math.degrees(math.acos(1.0 / math.sqrt(1.0 + tu * tu + tv * tv)))

    def focal_px(self) -> tuple[float, float]:
        """(f_x, f_y): the focal length in pixels across and up the image (needs
        ``resolution_px``): ``(w / 2) / tan(H / 2)`` and ``(h / 2) / tan(V / 2)``."""
        assert self.resolution_px is not None
        ha, va = self._half_fov()
        w, h = self.resolution_px
        return w / 2 / math.tan(ha), h / 2 / math.tan(va)

    def px_per_m(
        self, d_sensor: NDArray[np.float64], facing: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """(...,) pixels per metre on surfaces seen along unit directions ``d_sensor``
        (..., 3, sensor frame) with ``facing`` = |d.n| / r^2 (``facing_factor``):
        sqrt(f_x f_y |d.n| / (r^2 cos^3 t)), see the module docstring."""
        fx, fy = self.focal_px()
        fwd = np.clip(d_sensor[..., 0], 1e-12, None)
        return np.sqrt(fx * fy * facing / (fwd * fwd * fwd))

    def max_px_per_sr(self) -> float:
        """The highest pixels per steradian anywhere in the FoV (its corners):
        f_x f_y / cos^3 t at the corner; times ``facing`` it bounds px_per_m^2."""
        fx, fy = self.focal_px()
        ha, va = self._half_fov()
        tu, tv = math.tan(ha), math.tan(va)
        cos_corner = 1.0 / math.sqrt(1.0 + tu * tu + tv * tv)
        return fx * fy / cos_corner**3

    def ground_density(
        self,
        d_sensor: NDArray[np.float64],
        d_world: NDArray[np.float64],
        dist: NDArray[np.float64],
        normals: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """(N,) points per m^2 (XY projection) on surfaces with unit ``normals`` (N, 3),
        hit along unit directions (sensor frame ``d_sensor``, world ``d_world``) at
        distances ``dist`` (N,) m."""
        return self.rays_per_sr(d_sensor) * surface_factor(d_world, dist, normals)


@dataclass(frozen=True)
class SensorSpec:
    """One sensor as a user asks for it (a sensors file, a camera in the scene).

    World metres and degrees. ``height_m``: mast height above the ground under the
    sensor; when None, ``z`` (the optical centre's absolute world height, e.g. where a
    camera stands) sets it, and without either the sensor area's or the model's
    mount height applies.
    """

    model: SensorModel
    x: float
    y: float
    height_m: float | None
    pitch_deg: float
    yaw_deg: float
    z: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The sensors-file form (the model is written beside it)."""
        out: dict[str, Any] = {"x": self.x, "y": self.y}
        if self.height_m is not None:
            out["height_m"] = self.height_m
        out.update(pitch_deg=self.pitch_deg, yaw_deg=self.yaw_deg)
        return out


def surface_factor(
    d_world: NDArray[np.float64], dist: NDArray[np.float64], normals: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(N,) m^2 of XY-projected ground per steradian, inverted: |d.n| / (r^2 |n_z|).

    The orientation-free part of the density: points/m^2 = rays/sr x this factor.
    Written per component (not einsum) so each row's value does not depend on the
    other rows: cached and direct evaluators must agree to the last bit.
    """
    cos_i = np.abs(
        d_world[:, 0] * normals[:, 0]
        + d_world[:, 1] * normals[:, 1]
        + d_world[:, 2] * normals[:, 2]
    )
    nz = np.clip(np.abs(normals[:, 2]), _MIN_NZ, None)
    return cos_i / (np.maximum(dist, 1e-9) ** 2 * nz)


def facing_factor(
    d_world: NDArray[np.float64], dist: NDArray[np.float64], normals: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(N,) steradians per m^2 of the surface itself: |d.n| / r^2 (pixel density's
    orientation-free part; see the module docstring). Per component, as
    ``surface_factor``, so each row's value does not depend on the other rows."""
    cos_i = np.abs(
        d_world[:, 0] * normals[:, 0]
        + d_world[:, 1] * normals[:, 1]
        + d_world[:, 2] * normals[:, 2]
    )
    return cos_i / np.maximum(dist, 1e-9) ** 2


_OPTIONAL = ("pattern", "resolution_px", "min_px_per_m")


def _resolution(value: Any, label: str) -> tuple[int, int] | None:
    """``value`` as (width, height) in whole pixels, None for None; else InputError."""
    if value is None:
        return None
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise InputError(
            f"{label}: resolution_px must be [width, height] in pixels, got {brief(value)}"
        )
    why = " px (16K video, the widest, is 15,360)"
    w = whole_number(value[0], "resolution_px width", label, 1, MAX_PX_AXIS, why)
    h = whole_number(value[1], "resolution_px height", label, 1, MAX_PX_AXIS, why)
    return (w, h)


def _px_per_m(value: Any, label: str) -> float:
    """``value`` (px/m, or a DORI level name) as a float in [0, MAX_PX_PER_M]."""
    if isinstance(value, str):
        name = value.strip().lower()
        name = "recognise" if name == "recognize" else name
        if name not in DORI_PX_PER_M:
            raise InputError(
                f"{label}: min_px_per_m must be px/m or a DORI level "
                f"({', '.join(DORI_PX_PER_M)}), got {brief(value)}"
            )
        return DORI_PX_PER_M[name]
    why = " px/m (identify, the highest DORI level, is 250)"
    return number(value, "min_px_per_m", label, 0.0, MAX_PX_PER_M, why)


# --- presets ---------------------------------------------------------------------

PAPER_CAMERA = SensorModel(
    kind="camera",
    h_fov_deg=80.0,
    v_fov_deg=80.0,
    range_m=80.0,
    mount_height_m=7.0,
    pitch_min_deg=31.0,
    pitch_max_deg=70.0,
    rays_h=192,
    rays_v=160,
    min_density_per_m2=1.727,
    pattern="angular",
)
"""The paper's camera (Table I): 80 x 80 deg, 80 m effective range, 7 m mast,
30,720 sample points, pitch in [31, 70] deg.

Pattern: the paper's sensor is a game-engine ray-cast sensor (rays spaced evenly in
angle), so the pattern is ``angular``, 192 x 160 = 30,720 rays.

Detection threshold, and how it reproduces the paper's 1229.95 m^2: on flat ground a
sensor at height h sees a point at distance r with density
``rho = N / (H V cos b) * h / r^3`` (H = V = 80 deg in radians; see the module
docstring). The threshold D sets how far the footprint reaches. We solved for the D at
which the largest flat-ground footprint over the pitch range [31, 70] deg (frustum,
80 m range and rho >= D, integrated on a 0.1 m grid, pitch in 0.5 deg steps) equals
the paper's reference 1229.95 m^2: D = 1.727 points/m^2. The maximum sits at
pitch 49 deg, where the top of the FoV meets the density limit; from 31 to 49 deg the
footprint stays within 4 % of it (1180 to 1230 m^2), which is why the paper's sensors,
pitched 31 to 42 deg, average a relative coverage near 1.0. ``tests/core`` re-derives
this maximum with both coverage methods.
"""

ROADSIDE_LIDAR = SensorModel(
    kind="lidar",
    h_fov_deg=360.0,
    v_fov_deg=33.2,
    range_m=80.0,
    mount_height_m=5.0,
    pitch_min_deg=0.0,
    pitch_max_deg=25.0,
    rays_h=1024,
    rays_v=64,
    min_density_per_m2=1.0,
    pattern="angular",
)
"""A typical roadside lidar: a 64-beam spinning unit of the Ouster OS1-64 class.

Datasheet figures (OS1, 64 beams): vertical FoV +16.6 to -16.6 deg (33.2 deg),
horizontal 360 deg at 512/1024/2048 steps (1024 here), range 120 m on 80 %
reflective and 40 m on 10 % reflective targets. The effective range of 80 m is our
choice between those two figures (vehicle paint and plates mostly reflect more than
10 %). Threshold: 1 point/m^2, about eight returns on the 8 m^2 plan area of a car.
A 5 m mast and a downward tilt of 0 to 25 deg are typical roadside mounts.
"""

TRAFFIC_RADAR = SensorModel(
    kind="radar",
    h_fov_deg=100.0,
    v_fov_deg=16.0,
    range_m=150.0,
    mount_height_m=6.0,
    pitch_min_deg=0.0,
    pitch_max_deg=20.0,
    rays_h=100,
    rays_v=16,
    min_density_per_m2=0.0,
    pattern="angular",
)
"""A typical 77 GHz roadside traffic radar of the medium-range class.

Class figures, not one vendor's datasheet: about +-50 deg azimuth, a fan beam of about
16 deg in elevation, cars detected out to about 150 m, mounted 5 to 8 m high and
tilted slightly down. A radar sees what it has line of sight to within range and beam,
so the density threshold is 0; the 100 x 16 rays (one per degree) only resolve
occlusion.
"""

CCTV_CAMERA = SensorModel(
    kind="camera",
    h_fov_deg=80.0,
    v_fov_deg=50.534,
    range_m=50.0,
    mount_height_m=7.0,
    pitch_min_deg=15.0,
    pitch_max_deg=60.0,
    rays_h=192,
    rays_v=108,
    min_density_per_m2=0.0,
    pattern="pinhole",
    resolution_px=(1920, 1080),
    min_px_per_m=DORI_PX_PER_M["detect"],
)
"""A fixed 1080p CCTV camera with a wide lens, judged by pixel density (DORI).

1920 x 1080 pixels behind an 80 deg horizontal FoV (a 2.8 to 3.6 mm lens on a 1/2.8"
sensor); the vertical FoV, 50.534 deg = 2 atan(1080 / 1920 tan 40 deg), makes the
pixels square: f = 960 / tan 40 deg = 1144.1 px. It counts a point where it reaches
the DORI level ``detect`` (25 px/m); a target area with ``dori = "recognise"`` asks
for more there. On flat ground from the 7 m mast a level of p px/m reaches the depth
(f^2 7 / p^2)^(1/3) along the optical axis: 24.5 m for detect, 13.4 m for observe,
8.4 m for recognise, 5.3 m for identify (nearer than any ground from 7 m: the camera
cannot identify on the ground from that mast; mount it lower or use a longer lens).
The 50 m range passes detect on any surface (a face towards the camera reaches 25 px/m
to f / 25 = 46 m). Pitch 15 to 60 deg, the usual tilt of a pole-mounted camera. The
pattern's 192 x 108 rays (one per 10 x 10 pixels) only sample occlusion for the
point-cloud method; the density threshold is 0, the pixels decide.
"""

PRESETS: dict[str, SensorModel] = {
    "paper_camera": PAPER_CAMERA,
    "roadside_lidar": ROADSIDE_LIDAR,
    "traffic_radar": TRAFFIC_RADAR,
    "cctv_camera": CCTV_CAMERA,
}


@dataclass(frozen=True)
class SensorPack:
    """The sensor models one plan may mix on its masts, each with its own cost.

    models: (M,) distinct models, the first the run's main one (the ES and the
    single-model outputs use it); costs: (M,) what one sensor of each costs, in the
    units of ``mast_cost``; None: the settings' ``sensor_cost``.
    """

    models: tuple[SensorModel, ...]
    costs: tuple[float | None, ...]

    @classmethod
    def of(cls, model: SensorModel | SensorPack) -> SensorPack:
        """``model`` as a pack: a single model at the settings' sensor cost."""
        return model if isinstance(model, SensorPack) else cls((model,), (None,))

    @classmethod
    def from_spec(cls, specs: Any, label: str) -> SensorPack:
        """A pack from a list whose entries are a preset name or a table of model keys
        (as ``SensorModel.from_spec``) with an optional ``sensor_cost``; InputError
        naming ``label`` and the entry for any fault."""
        if not isinstance(specs, list) or not specs:
            raise InputError(f"{label}: models must be a non-empty list of models")
        models: list[SensorModel] = []
        costs: list[float | None] = []
        for k, spec in enumerate(specs, start=1):
            where = f"{label} {k}"
            cost = None
            if isinstance(spec, dict) and "sensor_cost" in spec:
                spec = dict(spec)
                cost = number(spec.pop("sensor_cost"), "sensor_cost", where, 0.0, 1e9)
            model = SensorModel.from_spec(spec, where)
            if model in models:
                raise InputError(f"{where}: the same model as entry {models.index(model) + 1}")
            models.append(model)
            costs.append(cost)
        return cls(tuple(models), tuple(costs))

    @property
    def mixed(self) -> bool:
        """Whether the pack holds more than one model."""
        return len(self.models) > 1

    def check_optimizer(self, optimizer: str) -> None:
        """InputError when ``optimizer`` cannot plan this pack: the ES plans one model."""
        if self.mixed and optimizer == "es":
            raise InputError(
                "the es optimizer plans one sensor model; a mixed pack needs "
                "--optimizer greedy or lp"
            )

    def cost_of(self, sensor_cost: float) -> NDArray[np.float64]:
        """(M,) the cost of one sensor of each model (None: ``sensor_cost``)."""
        return np.array([sensor_cost if c is None else c for c in self.costs], dtype=float)

    def to_list(self, sensor_cost: float) -> list[dict[str, Any]]:
        """The pack as result files record it: each model's keys and its cost."""
        return [
            {**m.to_dict(), "sensor_cost": float(c)}
            for m, c in zip(self.models, self.cost_of(sensor_cost))
        ]

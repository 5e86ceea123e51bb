"""A finished layout: what every output reads, in world coordinates, with no caster.

``finish_layout`` is the last stage of the core, shared by an optimization and by the
evaluation of a given layout: it combines the per-sensor coverages, converts poses,
masts, areas and target points to world metres, drapes every footprint on the ground
and computes the paper's metrics. The ``Result`` it returns is plain data: result.json,
sensors.csv, sensors.geojson, coverage.png and the objects spawned in Blender are all
written from it, and nothing after it casts a ray.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
import shapely.affinity
from numpy.typing import NDArray
from scipy import sparse
from scipy.sparse import csgraph
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from .coverage.base import SensorCoverage, footprint_polygon, summarize
from .coverage.reference import reference_footprint_m2
from .geom.drape import drape
from .geom.grid import GroundGrid
from .geom.outline import occluder_outline
from .model.scene import Area, Exclusion, SceneModel
from .model.sensors import SensorModel, SensorPack
from .optimize.base import PlanBound
from .problem import point_need

# ``Result.notes`` of a scene where nothing stands over ``geom.outline``'s height above
# the ground (the coverage map draws what does as occluders).
CLEAR_SIGHT_NOTE = (
    "nothing in the scene stands up from the ground (no wall, building or tree): "
    "sight lines are assumed clear but for the terrain"
)

F64 = NDArray[np.float64]
I32 = NDArray[np.int32]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class SensorRecord:
    """One placed sensor. World metres, degrees; ``mast`` indexes ``Result.masts``.

    footprint: the ground region it covers (density over the threshold, line of
    sight), a (Multi)Polygon in world XY; footprint_m2 its area. drape: the footprint
    as a mesh on the ground, vertices (V, 3) world metres and triangles (T, 3), or
    None (then it lies flat at the mast foot). sensor_area: the area it stands in.
    rays: sight rays its final evaluation cast. existing: it stood before the plan
    (given to the run, kept as it was, no cost).
    """

    n: int
    x: float
    y: float
    z: float
    height_m: float
    pitch_deg: float
    yaw_deg: float
    model: SensorModel
    mast: int
    fitness: float
    epochs: int
    covered_target_m2: float
    footprint_m2: float
    footprint: BaseGeometry
    drape: tuple[F64, I32] | None = None
    sensor_area: str | None = None
    rays: int = 0
    existing: bool = False


@dataclass(frozen=True)
class MastRecord:
    """A mast: world position of its foot (``z_ground``), height, the sensors on it
    (their ``n``); existing: it stands already (it carries an existing sensor)."""

    n: int
    x: float
    y: float
    z_ground: float
    height_m: float
    sensors: tuple[int, ...]
    existing: bool = False


@dataclass(frozen=True)
class Result:
    """Sensors, masts, areas and per-target-point coverage, all in world coordinates.

    points: (N, 3) target points; n_visible, n_covered: (N,) counts of sensors that
    see / cover each point; best_density: (N,) the highest density among the covering
    sensors (points/m^2, 0: none); cell_m: the target grid spacing (each point stands
    for cell_m^2 of ground). metrics: the paper's figures (see ``layout_metrics``);
    uncovered: the connected uncovered patches (``uncovered_parts``). scene: the
    source file's name; origin: (3,) the local origin the core worked in; settings:
    the settings (an ``OptimizeSettings`` or ``CoverageSettings``); model: the run's
    sensor model (None when each sensor brought its own; the main one of a mixed
    ``pack``, the models a plan mixed, None otherwise). occluder_outlines: the top
    view of the occluders that stand up from the terrain (buildings, walls, trees;
    ``geom.outline``), one Polygon per connected part in world XY, largest first.
    crs, crs_offset: the scene's georeference (``SceneModel.crs``; None: none), which
    the GIS outputs (``io.georef``) apply to these world coordinates. need: (N,)
    sensors each point needs to count as covered (its k; None: 1); area_k: the target
    areas that set their own ``coverage_k``, (name, k). excluded: the parts of the
    sensor areas where no mast may stand, and why (``SceneModel.excluded``).
    targets_fingerprint: which ground's targets these are
    (``SceneModel.targets_fingerprint``). interrupted: the run was interrupted (Ctrl-C,
    SIGTERM) and stopped early: the plan is the best it had by then.
    """

    sensors: tuple[SensorRecord, ...]
    masts: tuple[MastRecord, ...]
    targets: tuple[tuple[str, BaseGeometry], ...]
    sensor_areas: tuple[tuple[str, BaseGeometry], ...]
    points: F64
    n_visible: I32
    n_covered: I32
    cell_m: float
    best_density: F64 | None = None
    metrics: dict[str, Any] = field(default_factory=dict)
    stop_reason: str = ""
    uncovered: tuple[dict[str, Any], ...] = ()
    warnings: tuple[str, ...] = ()
    scene: str = ""
    origin: F64 = field(default_factory=lambda: np.zeros(3))
    settings: Any = None
    model: SensorModel | None = None
    pack: SensorPack | None = None
    target_polygon_m2: float = 0.0
    rays: dict[str, int] = field(default_factory=dict)
    occluder_outlines: tuple[Polygon, ...] = ()
    crs: str | None = None
    crs_offset: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    need: I32 | None = None
    area_k: tuple[tuple[str, int], ...] = ()
    excluded: tuple[Exclusion, ...] = ()
    targets_fingerprint: str = ""
    interrupted: bool = False

    @property
    def notes(self) -> tuple[str, ...]:
        """What a reader of the plan should know about the scene: that nothing in it
        stands up from the ground (an OpenDRIVE import, for one), so the sight lines
        were clear but for the terrain."""
        if self.occluder_outlines or not len(self.points):
            return ()
        return (CLEAR_SIGHT_NOTE,)

    @property
    def k_need(self) -> I32:
        """(N,) sensors each target point needs to count as covered: its target area's
        ``coverage_k`` or the settings' (``need``; all 1 when not given)."""
        if self.need is not None:
            return self.need
        return np.ones(len(self.n_covered), dtype=np.int32)

    @property
    def coverage_fraction(self) -> float:
        """Share of target points covered by their k sensors (k = 1: by any)."""
        n = len(self.n_covered)
        return float((self.n_covered >= self.k_need).mean()) if n else 0.0


@dataclass(frozen=True)
class Provenance:
    """How a layout came about, for its metrics and reports.

    fitness, epochs: per sensor (None: not optimized); evaluations, sight_rays: spent
    by the optimizer before the final evaluation; t0: ``time.perf_counter()`` when the
    work began (wall_s is measured from it). existing: per sensor, whether it stood
    already (None: none did); standing: (M, 2) local sites where masts stood already.
    model: the run's model, or the main one of a mixed ``pack`` (then each sensor
    brings its own); sensor_costs: per sensor, what it costs (None: the settings'
    ``sensor_cost`` each).
    """

    t0: float
    fitness: Sequence[float] | None = None
    epochs: Sequence[int] | None = None
    evaluations: int = 0
    sight_rays: int = 0
    stop_reason: str = ""
    warnings: tuple[str, ...] = ()
    settings: Any = None
    model: SensorModel | None = None
    bound: PlanBound | None = None
    existing: Sequence[bool] | None = None
    standing: F64 | None = None
    pack: SensorPack | None = None
    sensor_costs: Sequence[float] | None = None


def finish_layout(
    scene: SceneModel,
    grid: GroundGrid,
    coverages: Sequence[SensorCoverage],
    mast_of: Sequence[int],
    how: Provenance,
    extra_rays: int = 0,
    need: NDArray[np.int32] | None = None,
    pieces: Sequence[SensorPieces] = (),
) -> Result:
    """The ``Result`` of evaluated sensors (see the module docstring).

    scene, grid: what the coverages were computed on (local metres); coverages: one
    per sensor, evaluated in full (``outside_band_m=inf``, with visibility); mast_of:
    (n,) each sensor's mast label 0..m-1, a mast standing where its first sensor
    stands, as tall as its tallest; extra_rays: rays the caller cast outside
    evaluations and drops (reachability probes, candidate sets); need: (N,) sensors
    each target point needs (default: ``point_need`` of the grid and the settings'
    ``coverage_k``); pieces: per sensor, its ``sensor_pieces`` when the caller has
    them already (empty: made here).
    """
    if need is None:
        need = point_need(grid, int(getattr(how.settings, "coverage_k", 1) or 1))
    summary = summarize(grid, list(coverages))
    ox, oy, oz = (float(v) for v in scene.origin)
    sensors = []
    for k, cov in enumerate(coverages):
        p = cov.pose
        made = pieces[k] if pieces else sensor_pieces(scene, grid, cov)
        sensors.append(
            SensorRecord(
                n=k + 1,
                x=p.x + ox,
                y=p.y + oy,
                z=p.z + oz,
                height_m=p.height_m,
                pitch_deg=p.pitch_deg,
                yaw_deg=p.yaw_deg,
                model=cov.model,
                mast=int(mast_of[k]),
                fitness=float(how.fitness[k]) if how.fitness is not None else 0.0,
                epochs=int(how.epochs[k]) if how.epochs is not None else 0,
                covered_target_m2=len(cov.covered) * grid.cell_area,
                footprint_m2=float(cov.footprint_m2 or 0.0),
                footprint=made.footprint,
                drape=made.drape,
                sensor_area=made.sensor_area,
                rays=cov.rays,
                existing=bool(how.existing[k]) if how.existing is not None else False,
            )
        )
    # Local sites where masts stood already (compared in local metres, as placed).
    stood = set() if how.standing is None else {(float(x), float(y)) for x, y in how.standing}
    masts = []
    for label in range(max(mast_of, default=-1) + 1):
        members = [s for s in sensors if s.mast == label]
        first = members[0]
        foot = coverages[first.n - 1].pose
        masts.append(
            MastRecord(
                n=label + 1,
                x=first.x,
                y=first.y,
                z_ground=first.z - first.height_m,
                height_m=max(s.height_m for s in members),
                sensors=tuple(s.n for s in members),
                existing=any(s.existing for s in members) or (foot.x, foot.y) in stood,
            )
        )
    t_outline = time.perf_counter()
    outlines = tuple(
        shapely.affinity.translate(p, ox, oy) for p in occluder_outline(scene.vertices, scene.faces)
    )
    logger.debug(
        "occluder outline: %d parts from %d triangles in %.3f s",
        len(outlines),
        len(scene.faces),
        time.perf_counter() - t_outline,
    )
    sight = how.sight_rays + sum(c.rays for c in coverages)
    drop = grid.drop_rays
    metrics = layout_metrics(
        coverages,
        summary.n_covered,
        grid.spacing,
        n_masts=len(masts),
        epochs=how.epochs,
        evaluations=how.evaluations,
        wall_s=time.perf_counter() - how.t0,
        rays_cast=sight + drop + extra_rays,
        need=need,
        coverage_k=int(getattr(how.settings, "coverage_k", 1) or 1),
    )
    if hasattr(how.settings, "objective"):
        # Existing sensors and masts cost nothing: the objective is the new ones'.
        new_sensors = sum(not s.existing for s in sensors)
        new_masts = sum(not m.existing for m in masts)
        paid = None
        if how.sensor_costs is not None:
            paid = sum(c for c, s in zip(how.sensor_costs, sensors) if not s.existing)
        # The bounds are on the new ones too: standing masts cost nothing there.
        metrics.update(objective_metrics(new_sensors, new_masts, how.settings, how.bound, paid))
        metrics.update(
            existing_sensors=len(sensors) - new_sensors, existing_masts=len(masts) - new_masts
        )

    def world(areas):
        return tuple((a.name, shapely.affinity.translate(a.geometry, ox, oy)) for a in areas)

    return Result(
        sensors=tuple(sensors),
        masts=tuple(masts),
        targets=world(scene.targets),
        sensor_areas=world(scene.sensor_areas),
        points=scene.to_world(grid.target_points),
        n_visible=summary.n_visible,
        n_covered=summary.n_covered,
        cell_m=grid.spacing,
        best_density=summary.best_density,
        metrics=metrics,
        stop_reason=how.stop_reason,
        uncovered=tuple(uncovered_parts(grid, summary.n_covered < need, scene)),
        warnings=how.warnings,
        scene=scene.source,
        origin=np.asarray(scene.origin, dtype=float),
        settings=how.settings,
        model=how.model,
        pack=how.pack,
        target_polygon_m2=round(float(scene.target_union.area), 2),
        rays={"sight": sight, "drop": drop, "probe": extra_rays},
        occluder_outlines=outlines,
        crs=scene.crs,
        crs_offset=scene.crs_offset,
        need=need,
        area_k=tuple((a.name, int(a.coverage_k)) for a in scene.targets if a.coverage_k),
        excluded=scene.excluded,
        targets_fingerprint=scene.targets_fingerprint(),
    )


@dataclass(frozen=True)
class SensorPieces:
    """What the report draws of one evaluated sensor, in world metres: its footprint
    (a (Multi)Polygon in XY), that footprint draped on the ground (vertices (V, 3),
    triangles (T, 3); None when it is empty) and the name of the sensor area it
    stands in (None: none)."""

    footprint: BaseGeometry
    drape: tuple[F64, I32] | None
    sensor_area: str | None


def sensor_pieces(scene: SceneModel, grid: GroundGrid, cov: SensorCoverage) -> SensorPieces:
    """The ``SensorPieces`` of a sensor evaluated in full on ``grid`` (local metres):
    about 10 ms a sensor on Town04, most of it the drape."""
    ox, oy, oz = (float(v) for v in scene.origin)

    def ground_world(xy_world: F64) -> F64:
        return grid.ground_z(xy_world - (ox, oy)) + oz

    footprint = shapely.affinity.translate(footprint_polygon(grid, cov), ox, oy)
    return SensorPieces(
        footprint=footprint,
        drape=drape(footprint, ground_world) if not footprint.is_empty else None,
        sensor_area=getattr(area_at(scene, cov.pose.x, cov.pose.y), "name", None),
    )


def layout_metrics(
    coverages: Sequence[SensorCoverage],
    n_covered: NDArray[np.int32],
    grid_m: float,
    n_masts: int,
    epochs: Sequence[int] | None,
    evaluations: int,
    wall_s: float,
    rays_cast: int,
    need: NDArray[np.int32] | None = None,
    coverage_k: int = 1,
) -> dict[str, Any]:
    """The paper's metrics of a layout.

    coverage_fraction, covered_m2: the points covered by their k sensors (``need``,
    (N,), default 1 each: the paper's); coverage_k: the settings' k, coverage_k_max:
    the largest k of any point (a target area may ask more); coverage_by_k: for k =
    1, 2, 3 the fraction and m^2 of the target covered by at least k sensors;
    target_area_m2; sensors, masts, cluster_ratio =
    masts / sensors; relative_sensor_coverage = mean footprint / the model's largest
    flat-ground footprint (``reference_footprint_m2``; with several models, the mean
    of each sensor's ratio); overlap_factor = sum of per-sensor covered target m^2 /
    target m^2; mean_epochs_per_sensor (None when not optimized); evaluations, wall_s,
    rays_cast. Ratios are None for a layout with no sensor (relative_sensor_coverage
    also when no sensor's model has a reference footprint).
    """
    n = len(coverages)
    cell_area = grid_m**2
    target_m2 = len(n_covered) * cell_area
    refs = [reference_footprint_m2(c.model, grid_m) for c in coverages]
    footprints = [c.footprint_m2 or 0.0 for c in coverages]
    # A model whose threshold no flat ground meets has no reference footprint: its
    # sensors have no ratio (all of them: none).
    ratios = [f / r for f, r in zip(footprints, refs) if r > 0]
    relative = round(float(np.mean(ratios)), 4) if ratios else None
    k = np.ones(len(n_covered), dtype=np.int32) if need is None else need
    covered = int(np.count_nonzero(n_covered >= k))
    return {
        "coverage_fraction": round(covered / max(len(n_covered), 1), 6),
        "covered_m2": covered * cell_area,
        "coverage_k": int(coverage_k),
        "coverage_k_max": int(k.max()) if len(k) else int(coverage_k),
        "coverage_by_k": coverage_by_k(n_covered, cell_area),
        "target_area_m2": target_m2,
        "sensors": n,
        "masts": n_masts,
        "cluster_ratio": round(n_masts / n, 4) if n else None,
        "relative_sensor_coverage": relative,
        "reference_footprint_m2": round(refs[0], 2) if n and len(set(refs)) == 1 else None,
        "overlap_factor": round(sum(len(c.covered) for c in coverages) * cell_area / target_m2, 4),
        "mean_epochs_per_sensor": round(float(np.mean(epochs)), 2) if n and epochs else None,
        "evaluations": evaluations,
        "wall_s": round(wall_s, 2),
        "rays_cast": rays_cast,
    }


def coverage_by_k(
    n_covered: NDArray[np.int32], cell_area: float, ks: Sequence[int] = (1, 2, 3)
) -> dict[str, dict[str, float]]:
    """For each k of ``ks`` (keys "1", "2", ...): the fraction of the target points
    covered by at least k sensors and the m^2 they stand for."""
    n = max(len(n_covered), 1)
    out = {}
    for k in ks:
        hit = int(np.count_nonzero(np.asarray(n_covered) >= k))
        out[str(k)] = {"fraction": round(hit / n, 6), "m2": round(hit * cell_area, 4)}
    return out


def objective_metrics(
    sensors: int,
    masts: int,
    settings: Any,
    bound: PlanBound | None,
    sensors_cost: float | None = None,
) -> dict[str, Any]:
    """The plan's objective and, when one was proven, the lower bound on it.

    cost = mast_cost x masts + what the sensors cost (``sensors_cost``; None:
    sensor_cost x sensors); objective: the value of the
    settings' objective (cost, sensors or masts); lower_bound: no plan in
    ``bound_scope`` has a lower objective; gap = (objective - lower_bound) / objective;
    sensors_lower_bound, masts_lower_bound: the bounds on each part; joint_lower_bound:
    on the cost from masts and sensors together (``joint.py``; None: not proven);
    sensors_on_masts_lower_bound: no plan whose new sensors stand on this plan's masts
    (or those that stood already) has fewer new sensors (None: not proven); lp_bound:
    the LP relaxation's bound on the sensors, before rounding up (with models of
    different costs: on what the sensors cost).
    """
    if sensors_cost is None:
        sensors_cost = settings.sensor_cost * sensors
    cost = settings.mast_cost * masts + sensors_cost
    value = {"cost": cost, "sensors": sensors, "masts": masts}[settings.objective]
    out: dict[str, Any] = {
        "cost": round(cost, 4),
        "objective": round(float(value), 4),
        "lower_bound": None,
        "gap": None,
        "sensors_lower_bound": None,
        "masts_lower_bound": None,
        "joint_lower_bound": None,
        "sensors_on_masts_lower_bound": None,
        "lp_bound": None,
        "lp_rounds": None,
        "bound_scope": None,
    }
    if bound is not None:
        lower = bound.objective(settings.objective, settings.mast_cost, settings.sensor_cost)
        out.update(
            lower_bound=round(lower, 4),
            gap=round((value - lower) / value, 4) if value > 0 else 0.0,
            sensors_lower_bound=bound.sensors,
            masts_lower_bound=bound.masts,
            joint_lower_bound=round(bound.joint, 4) if bound.joint > 0 else None,
            sensors_on_masts_lower_bound=bound.on_masts,
            lp_bound=round(bound.lp, 4),
            lp_rounds=bound.rounds,
            bound_scope=bound.scope,
        )
    return out


def area_at(scene: SceneModel, x: float, y: float) -> Area | None:
    """The first sensor area holding local (x, y) (border included), or None."""
    for area in scene.sensor_areas:
        if shapely.intersects_xy(area.geometry, x, y):
            return area
    return None


def uncovered_parts(
    grid: GroundGrid, uncovered: NDArray[np.bool_], scene: SceneModel, min_m2: float = 0.0
) -> list[dict[str, Any]]:
    """Connected patches of uncovered target points (8-neighbour), largest first.

    Each: the target area's name, m^2, and the patch centroid in world x, y. Patches
    are found among the uncovered points alone (a graph of their neighbours), never
    on a raster of the ground; numbered, as ``ndimage.label`` numbers them, by their
    first cell in the lattice's order, which orders patches of equal m^2.
    """
    if not uncovered.any():
        return []
    cells = grid.target_cells[uncovered]  # sorted
    i, j = np.divmod(cells, grid.ny)
    # Each point's neighbours later in the lattice's order: the three on the next row
    # and the next one on its own row.
    links = []
    for di, dj in ((0, 1), (1, -1), (1, 0), (1, 1)):
        ok = (j + dj >= 0) & (j + dj < grid.ny) & (i + di < grid.nx)
        other = cells + di * grid.ny + dj
        at = np.minimum(np.searchsorted(cells, other), len(cells) - 1)
        ok &= cells[at] == other
        links.append((np.flatnonzero(ok), at[ok]))
    a = np.concatenate([p for p, _ in links])
    b = np.concatenate([q for _, q in links])
    n = len(cells)
    graph = sparse.coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(n, n))
    count, found = csgraph.connected_components(graph, directed=False)
    # Number the patches by their first point (points are in the lattice's order).
    first = np.full(count, n)
    np.minimum.at(first, found, np.arange(n))
    rank = np.empty(count, dtype=np.int64)
    rank[np.argsort(first)] = np.arange(count)
    label = rank[found]
    # Each patch's members: indices into the target arrays, ascending.
    members_of = np.flatnonzero(uncovered)[np.argsort(label, kind="stable")]
    bounds = np.searchsorted(np.sort(label), np.arange(count + 1))
    parts: list[dict[str, Any]] = []
    for k in range(count):
        members = members_of[bounds[k] : bounds[k + 1]]
        m2 = len(members) * grid.cell_area
        if m2 < min_m2:
            continue
        cx, cy = scene.to_world(grid.target_xy[members].mean(axis=0))
        region = int(np.bincount(grid.target_region[members]).argmax())
        parts.append(
            {
                "target": scene.targets[region].name,
                "m2": m2,
                "x": round(float(cx), 2),
                "y": round(float(cy), 2),
            }
        )
    parts.sort(key=lambda p: -p["m2"])
    return parts

"""coverage.png: a top-view map of a sensor layout that explains itself.

Drawn with matplotlib's Agg renderer on a ``Figure`` of its own (no pyplot, so no GUI
backend and no global figure state) under matplotlib's default style, whatever a
user's matplotlibrc says; geometry goes in through ``shapely.plotting``. matplotlib
is imported inside ``coverage_figure`` only: the add-on registers without it, and
inside Blender it comes from the extension's bundled wheel.

What the map shows
------------------
Frame: world metres, x east, y north, equal scale, north up, labelled axes and a
scale bar (m, or km from 1 km). The view is the box around the targets, sensor
areas, footprints, masts and target points, grown by ``margin_m``; occluders
reaching beyond it are cut off at the frame.

Title: the scene's name; under it the plan in numbers: sensors and masts, coverage
(percent of the target grid, and its m^2), with k > 1 the share covered k times,
and for an optimization its objective with the proven lower bound and the gap, or
"no lower bound"; then, in grey, how it was made: optimizer and coverage goal (or
"evaluated layout"), sensor model, cost rule, target grid.

Layers, bottom to top: target areas (pale sand, dark outline drawn again on top),
sensor areas (light violet), sensor footprints (translucent blue; when a plan mixes
kinds, each kind its own colour: ``KIND_FILL``, a legend entry each; overlaps come
out darker), occluders (solid grey: buildings, walls, trees, ``Result.
occluder_outlines``), target cells no sensor covers (orange; with k > 1 every
target cell, coloured by how many sensors cover it, 0 .. k), the m^2 of the largest
uncovered patches, masts (dark discs with their number as in sensors.csv). Blue and
orange keep covered and uncovered apart for readers with red-green colour blindness
too. The legend beside the map names every layer present, with counts.

Size: ``width_px`` wide at 100 dpi; the map takes the left part at the view's
aspect (at most 1.6 high per 1 wide), the legend a 3.5 in column on the right.

The PNG carries no software, version or time stamp: the same result gives the same
bytes (on the same matplotlib and fonts).

One module: the map, its legend column, title and scale bar are laid out together on
one figure.
"""

from __future__ import annotations

import io
import logging
import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from ..core.result import Result

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

logger = logging.getLogger(__name__)

# Colours (matplotlib colour strings). Blue/orange for covered/uncovered is safe for
# red-green colour blindness; the target's sand and the occluders' grey differ in
# lightness, so they stay apart in greyscale too.
BACKGROUND = "#ffffff"
TARGET_FILL = "#f7f2dc"
TARGET_EDGE = "#5b5346"
SENSOR_AREA_FILL = "#e3d3f1"
SENSOR_AREA_EDGE = "#7b3fa8"
FOOTPRINT_FILL = "#1f6fc5"
FOOTPRINT_ALPHA = 0.3  # per footprint: two overlapping ones give 1 - 0.7^2
FOOTPRINT_EDGE = "#1b4f80"
# Footprints of a plan that mixes sensor kinds: blue, bluish green and reddish purple
# (Okabe-Ito), apart from each other and from the uncovered orange for every common
# colour blindness.
KIND_FILL = {"camera": FOOTPRINT_FILL, "lidar": "#009e73", "radar": "#cc79a7"}
OCCLUDER_FILL = "#707070"
OCCLUDER_EDGE = "#4a4a4a"
UNCOVERED = "#f26b0f"
MAST_FILL = "#1c1c1c"
MAST_TEXT = "#ffffff"
# k > 1: cells covered by 1 .. k sensors (k: k or more) take viridis from yellow
# (K_CMAP_LOW) to dark blue (K_CMAP_HIGH); 0 stays UNCOVERED.
K_CMAP = "viridis"
K_CMAP_LOW, K_CMAP_HIGH = 0.95, 0.25

GAP_TEXT = "#a63603"  # darker orange: readable on white
GAP_LABELS = 6
GAP_LABEL_MIN_M2 = 20.0

DPI = 100
MIN_WIDTH_PX = 800  # below this the legend column leaves the map too little room
LEGEND_WIDTH_IN = 3.5
LEFT_IN, GAP_IN, RIGHT_IN = 0.95, 0.3, 0.1
TOP_IN, BOTTOM_IN = 1.0, 0.65
MIN_HEIGHT_IN = 6.0  # room for the legend beside a wide, low map
MAX_MAP_ASPECT = 1.6  # taller scenes get a narrower map rather than a very tall image
FONT = 10


# --------------------------------------------------------------------------- public API


def render_png(
    result: Result,
    width_px: int = 1200,
    margin_m: float = 10.0,
    k_required: int | None = None,
) -> bytes:
    """The coverage map (see the module docstring) as PNG bytes, ``width_px`` wide.

    k_required: the coverage the plan asks for per target point; None reads the
    result's per-point k (``Result.need``: a target area may ask more than the
    settings), else ``result.settings.coverage_k`` (or ``k``), and falls back to 1.
    With k > 1 every target cell is coloured by how many sensors cover it.
    """
    from matplotlib.style import context

    t0 = time.perf_counter()
    fig = coverage_figure(result, width_px, margin_m, k_required)
    buf = io.BytesIO()
    # "Software" is the only metadata Agg writes by default; without it the bytes
    # depend on the result alone. The default style again: savefig reads rcParams.
    with context("default"):
        fig.savefig(buf, format="png", dpi=DPI, facecolor=BACKGROUND, metadata={"Software": None})
    data = buf.getvalue()
    logger.debug("coverage map %d bytes in %.3f s", len(data), time.perf_counter() - t0)
    return data


def coverage_figure(
    result: Result,
    width_px: int = 1200,
    margin_m: float = 10.0,
    k_required: int | None = None,
) -> Figure:
    """The map as a matplotlib ``Figure`` with an Agg canvas, not yet drawn; its one
    Axes is the map in world metres (``fig.axes[0]``)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.style import context

    n_points = len(result.points)
    if len(result.n_covered) != n_points:
        raise ValueError(f"result has {n_points} points but {len(result.n_covered)} n_covered")
    if width_px < MIN_WIDTH_PX:
        raise ValueError(f"width_px must be at least {MIN_WIDTH_PX}, got {width_px}")
    if margin_m < 0:
        raise ValueError(f"margin_m must not be negative, got {margin_m}")
    k = int(k_required if k_required is not None else required_k(result))
    if k < 1:
        raise ValueError(f"k_required must be at least 1, got {k}")

    box = view_box(result, margin_m)
    width_in = width_px / DPI
    fig_h, axes_rect = _layout(box, width_in)
    with context("default"):
        fig = Figure(figsize=(width_in, fig_h), dpi=DPI, facecolor=BACKGROUND)
        FigureCanvasAgg(fig)
        ax = fig.add_axes(axes_rect)
        _draw_map(ax, result, k)
        ax.set_xlim(box[0], box[2])
        ax.set_ylim(box[1], box[3])
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x east [m]", fontsize=FONT)
        ax.set_ylabel("y north [m]", fontsize=FONT)
        ax.ticklabel_format(useOffset=False, style="plain")
        ax.tick_params(labelsize=FONT - 1)
        ax.grid(True, color="#000000", alpha=0.08, linewidth=0.6)
        ax.set_axisbelow(True)
        _scale_bar(ax, box[2] - box[0])
        _title(fig, result, k, axes_rect[0], fig_h)
        fig.legend(
            handles=_legend_handles(result, k),
            loc="upper left",
            bbox_to_anchor=(
                axes_rect[0] + axes_rect[2] + GAP_IN / width_in,
                axes_rect[1] + axes_rect[3],
            ),
            frameon=False,
            fontsize=FONT - 1,
            title="Legend",
            title_fontproperties={"weight": "bold", "size": FONT},
            alignment="left",
            handlelength=1.6,
            handleheight=1.1,
            labelspacing=0.7,
        )
    return fig


def summary(result: Result, k: int = 1) -> str:
    """The line under the title: the plan in numbers.

    "12 sensors on 5 masts · coverage 93.4 % of 8,120 m^2 · cost 17 >= lower bound 15
    (gap 11.8 %)", with k > 1 also "covered by >= k sensors: 80.1 %", "no lower bound"
    when an optimization proved none; an evaluated layout has no objective and shows
    none.
    """
    m = result.metrics
    sensors = m.get("sensors", len(result.sensors))
    masts = m.get("masts", len(result.masts))
    fraction = m.get("coverage_fraction", result.coverage_fraction)
    if k > 1:  # coverage by any sensor first; the k-coverage next
        fraction = k_fraction(result, 1)
    parts = [f"{sensors} sensor{'s' * (sensors != 1)} on {masts} mast{'s' * (masts != 1)}"]
    cover = f"coverage {100 * fraction:.1f} %"
    if m.get("target_area_m2"):
        cover += f" of {m['target_area_m2']:,.0f} m²"
    parts.append(cover)
    need = result.need
    if k > 1 and need is not None and len(need) and int(need.min()) != int(need.max()):
        to_k = float((np.asarray(result.n_covered) >= need).mean())
        parts.append(
            f"covered to each area's k ({int(need.min())}–{int(need.max())}): {100 * to_k:.1f} %"
        )
    elif k > 1:
        parts.append(f"covered by ≥ {k} sensors: {100 * k_fraction(result, k):.1f} %")
    if m.get("objective") is not None:
        name = str(getattr(result.settings, "objective", "objective"))
        if m.get("lower_bound") is not None and m.get("gap") is not None:
            parts.append(
                f"{name} {m['objective']:g} ≥ lower bound {m['lower_bound']:g} "
                f"(gap {100 * m['gap']:.1f} %)"
            )
        else:
            parts.append(f"{name} {m['objective']:g}, no lower bound")
    return "  ·  ".join(parts)


def details(result: Result) -> str:
    """The grey line under the summary: how the plan was made (optimizer and coverage
    goal, or "evaluated layout"), the sensor model, the cost rule, the target grid, and
    "no occluder" where nothing in the scene stands up from the ground
    (``Result.notes``)."""
    settings = result.settings
    parts = []
    if getattr(settings, "optimizer", None):
        goal = getattr(settings, "rho", None)
        parts.append(
            f"{settings.optimizer} optimizer"
            + (f", coverage goal {100 * goal:g} %" if goal is not None else "")
        )
    elif result.sensors:
        parts.append("evaluated layout")
    model = result.model
    if model is None and len({s.model for s in result.sensors}) == 1:
        model = result.sensors[0].model
    if result.pack is not None:
        parts.append("mixed: " + ", ".join(m.kind for m in result.pack.models))
    elif model is not None:
        parts.append(
            f"{model.kind} {model.h_fov_deg:g}° × {model.v_fov_deg:g}°, {model.range_m:g} m range"
        )
    if getattr(settings, "objective", None) == "cost":
        per_sensor = f"{settings.sensor_cost:g} per sensor"
        if result.pack is not None:
            costs = result.pack.cost_of(settings.sensor_cost)
            per_sensor = ", ".join(f"{c:g} per {m.kind}" for m, c in zip(result.pack.models, costs))
        parts.append(f"cost = {settings.mast_cost:g} per mast + {per_sensor}")
    if len(result.points):
        parts.append(f"{result.cell_m:g} m target grid")
    if result.notes:  # nothing stands up from the ground
        parts.append("no occluder: sight lines assumed clear")
    return "  ·  ".join(parts)


def required_k(result: Result) -> int:
    """The k the map colours up to: the largest of the result's per-point k
    (``Result.need``), else the settings' ``coverage_k`` (or ``k``), else 1."""
    if result.need is not None and len(result.need):
        return max(1, int(np.max(result.need)))
    settings = result.settings
    k = getattr(settings, "coverage_k", None) or getattr(settings, "k", None) or 1
    return int(k)


def k_fraction(result: Result, k: int) -> float:
    """Share of target points covered by at least ``k`` sensors (0 with no points)."""
    n = np.asarray(result.n_covered)
    return float((n >= k).mean()) if len(n) else 0.0


def view_box(result: Result, margin_m: float = 10.0) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) world metres the map shows: targets, sensor areas,
    non-empty footprints, masts and target cells, grown by ``margin_m``; a box at
    least 1 m wide and high (10 m around the origin for an empty result)."""
    geoms = [g for _, g in result.targets] + [g for _, g in result.sensor_areas]
    geoms += [s.footprint for s in result.sensors]
    boxes = [g.bounds for g in geoms if not g.is_empty]
    boxes += [(m.x, m.y, m.x, m.y) for m in result.masts]
    if len(result.points):
        pts = np.asarray(result.points)[:, :2]
        half = result.cell_m / 2
        boxes.append((*(pts.min(axis=0) - half), *(pts.max(axis=0) + half)))
    if not boxes:
        boxes = [(-5.0, -5.0, 5.0, 5.0)]
    b = np.array(boxes, dtype=float)
    xmin, ymin = b[:, 0].min() - margin_m, b[:, 1].min() - margin_m
    xmax, ymax = b[:, 2].max() + margin_m, b[:, 3].max() + margin_m
    # A single point, or a line, still needs an area to show.
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
    half_w, half_h = max(xmax - xmin, 1.0) / 2, max(ymax - ymin, 1.0) / 2
    return (cx - half_w, cy - half_h, cx + half_w, cy + half_h)


def scale_bar_length(world_width_m: float) -> float:
    """The scale bar's length in metres: the largest 1, 2 or 5 x 10^n not over a fifth
    of the map's width."""
    target = max(world_width_m / 5, 1e-9)
    decade = 10.0 ** math.floor(math.log10(target))
    return max(m * decade for m in (1.0, 2.0, 5.0) if m * decade <= target * (1 + 1e-12))


def length_label(metres: float) -> str:
    """ "20 m", "500 m", "1 km", "2.5 km"."""
    if metres >= 1000:
        return f"{metres / 1000:g} km"
    return f"{metres:g} m"


# ------------------------------------------------------------------------------ layout


def _layout(
    box: tuple[float, float, float, float], width_in: float
) -> tuple[float, tuple[float, float, float, float]]:
    """Figure height (in) and the map's axes rectangle (figure fractions) for a
    ``width_in`` wide figure: the map left, the legend column right, the title above;
    the axes box has the view box's aspect, so equal scale leaves no blank strips."""
    aspect = (box[3] - box[1]) / (box[2] - box[0])
    map_w = width_in - LEFT_IN - GAP_IN - LEGEND_WIDTH_IN - RIGHT_IN
    map_h = map_w * aspect
    if aspect > MAX_MAP_ASPECT:
        map_h = map_w * MAX_MAP_ASPECT
        map_w = map_h / aspect
    fig_h = max(map_h + TOP_IN + BOTTOM_IN, MIN_HEIGHT_IN)
    bottom = fig_h - TOP_IN - map_h  # top-aligned: spare height goes below
    rect = (LEFT_IN / width_in, bottom / fig_h, map_w / width_in, map_h / fig_h)
    return fig_h, rect


# ----------------------------------------------------------------------------- drawing


def _polygons(geom: BaseGeometry) -> list[Polygon]:
    """The non-empty Polygons in a Polygon, MultiPolygon or (nested) collection; lines
    and points have no area and are dropped."""
    out: list[Polygon] = []
    for part in shapely.get_parts(geom):
        if isinstance(part, Polygon):
            if not part.is_empty:
                out.append(part)
        elif hasattr(part, "geoms"):
            out += _polygons(part)
    return out


def _patches(geoms: list[BaseGeometry], **style: Any) -> Any:
    """One PatchCollection of every polygon in ``geoms`` (holes stay open)."""
    from matplotlib.collections import PatchCollection
    from shapely.plotting import patch_from_polygon

    patches = [patch_from_polygon(p) for g in geoms for p in _polygons(g)]
    return PatchCollection(patches, **style)


def _cells(xy: NDArray[np.float64], cell_m: float, colours: Any, zorder: float) -> Any:
    """Squares of side ``cell_m`` centred on ``xy`` (N, 2): the target grid's cells."""
    from matplotlib.collections import PolyCollection

    h = cell_m / 2
    corners = np.array([[-h, -h], [h, -h], [h, h], [-h, h]])
    verts = xy[:, None, :] + corners[None, :, :]
    return PolyCollection(
        verts, facecolors=colours, edgecolors="none", antialiased=False, zorder=zorder
    )


def covered_colour() -> str:
    """The target's colour under one footprint layer."""
    from matplotlib.colors import to_hex, to_rgb

    under, over = np.array(to_rgb(TARGET_FILL)), np.array(to_rgb(FOOTPRINT_FILL))
    return to_hex(under + (over - under) * FOOTPRINT_ALPHA)


def k_colours(k: int) -> list[str]:
    """Colours of cells covered by 0, 1, ..., k sensors (the last: k or more)."""
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    cmap = colormaps[K_CMAP]
    steps = np.linspace(K_CMAP_LOW, K_CMAP_HIGH, k)
    return [UNCOVERED, *[to_hex(cmap(float(t))) for t in steps]]


def _draw_map(ax: Axes, result: Result, k: int) -> None:
    """Every layer of the map, in world metres, in the order the module docstring gives."""
    targets = [g for _, g in result.targets]
    areas = [g for _, g in result.sensor_areas]
    ax.add_collection(
        _patches(targets, facecolor=TARGET_FILL, edgecolor="none", linewidth=0, zorder=1)
    )
    ax.add_collection(
        _patches(areas, facecolor=SENSOR_AREA_FILL, edgecolor=SENSOR_AREA_EDGE, linewidth=1.0,
                 zorder=1.5)
    )  # fmt: skip
    for _, fill, footprints in _footprints_by_colour(result):
        ax.add_collection(
            _patches(footprints, facecolor=fill, alpha=FOOTPRINT_ALPHA, edgecolor="none",
                     zorder=2)
        )  # fmt: skip
        ax.add_collection(
            _patches(footprints, facecolor="none", edgecolor=FOOTPRINT_EDGE, linewidth=0.5,
                     alpha=0.6, zorder=2.1)
        )  # fmt: skip
    ax.add_collection(
        _patches(list(result.occluder_outlines), facecolor=OCCLUDER_FILL,
                 edgecolor=OCCLUDER_EDGE, linewidth=0.5, zorder=3)
    )  # fmt: skip

    if len(result.points):
        xy = np.asarray(result.points, dtype=float)[:, :2]
        n = np.asarray(result.n_covered)
        if k > 1:
            colours = np.array(k_colours(k))[np.minimum(n, k)]
            ax.add_collection(_cells(xy, result.cell_m, colours, zorder=4))
        elif (n == 0).any():
            ax.add_collection(_cells(xy[n == 0], result.cell_m, UNCOVERED, zorder=4))

    ax.add_collection(
        _patches(targets, facecolor="none", edgecolor=TARGET_EDGE, linewidth=0.9, zorder=5)
    )
    _label_gaps(ax, result)
    for mast in result.masts:
        ax.text(
            mast.x,
            mast.y,
            str(mast.n),
            ha="center",
            va="center",
            color=MAST_TEXT,
            fontsize=FONT - 3,
            fontweight="bold",
            zorder=7,
            gid=f"mast-{mast.n}",
            bbox={"boxstyle": "circle,pad=0.28", "fc": MAST_FILL, "ec": "white", "lw": 0.8},
        )


def _footprints_by_colour(result: Result) -> list[tuple[str | None, str, list[Any]]]:
    """(kind, fill colour, non-empty footprints) per sensor kind when the plan mixes
    kinds (``KIND_FILL``), else one entry (kind None) in the footprint blue."""
    kinds = sorted({s.model.kind for s in result.sensors}, key=list(KIND_FILL).index)
    out = []
    for kind in kinds if len(kinds) > 1 else [None]:
        fill = FOOTPRINT_FILL if kind is None else KIND_FILL[kind]
        shapes = [
            s.footprint
            for s in result.sensors
            if not s.footprint.is_empty and kind in (None, s.model.kind)
        ]
        if shapes:
            out.append((kind, fill, shapes))
    return out


def _label_gaps(ax: Axes, result: Result) -> None:
    """The m^2 of the largest uncovered patches (``Result.uncovered``), beside their
    centroids: at most ``GAP_LABELS``, each at least ``GAP_LABEL_MIN_M2``."""
    from matplotlib.patheffects import withStroke

    big = [p for p in result.uncovered if p["m2"] >= GAP_LABEL_MIN_M2][:GAP_LABELS]
    for patch in big:
        ax.annotate(
            f"{patch['m2']:,.0f} m²",
            (patch["x"], patch["y"]),
            xytext=(7, -7),
            textcoords="offset points",
            ha="left",
            va="top",
            fontsize=FONT - 2,
            fontweight="bold",
            color=GAP_TEXT,
            zorder=6,
            path_effects=[withStroke(linewidth=2.5, foreground="white")],
        )


def _title(fig: Figure, result: Result, k: int, left: float, fig_h: float) -> None:
    """Scene name, ``summary`` and ``details`` above the map, from its left edge; a
    line too long for the figure is set smaller until it fits."""
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    lines: tuple[tuple[str, float, str, str, float], ...] = (
        (result.scene or "coverage map", FONT + 4, "bold", "black", 0.12),
        (summary(result, k), FONT + 1, "normal", "black", 0.45),
        (details(result), FONT - 1, "normal", "#555555", 0.70),
    )
    for text, size, weight, colour, from_top_in in lines:
        if not text:
            continue
        artist = fig.text(left, 1 - from_top_in / fig_h, text, ha="left", va="top",
                          fontsize=size, fontweight=weight, color=colour)  # fmt: skip
        while size > 6 and artist.get_window_extent(renderer).x1 > fig.bbox.width - 8:
            size -= 0.5
            artist.set_fontsize(size)


def _scale_bar(ax: Axes, world_width_m: float) -> None:
    from matplotlib.font_manager import FontProperties
    from mpl_toolkits.axes_grid1.anchored_artists import (  # type: ignore[import-untyped]
        AnchoredSizeBar,
    )

    length = scale_bar_length(world_width_m)
    bar = AnchoredSizeBar(
        ax.transData,
        length,
        length_label(length),
        loc="lower left",
        pad=0.4,
        borderpad=0.8,
        sep=4,
        frameon=True,
        size_vertical=world_width_m / 200,
        color="black",
        fontproperties=FontProperties(size=FONT - 1),
        zorder=8,
    )
    bar.patch.set_facecolor("white")
    bar.patch.set_alpha(0.85)
    bar.patch.set_edgecolor("#999999")
    ax.add_artist(bar)


def _legend_handles(result: Result, k: int) -> list[Any]:
    """Proxy artists for the legend: one per layer present, with its counts."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Any] = []
    n = np.asarray(result.n_covered)
    if result.targets:
        area = result.metrics.get("target_area_m2") or sum(g.area for _, g in result.targets)
        handles.append(
            Patch(fc=TARGET_FILL, ec=TARGET_EDGE, lw=0.9,
                  label=f"target area: roads to watch ({area:,.0f} m²)")
        )  # fmt: skip
    if len(n) and k > 1:
        counts = np.bincount(np.minimum(n, k), minlength=k + 1)
        for level, colour in enumerate(k_colours(k)):
            who = f"{level} sensor{'s' * (level != 1)}" + (" or more" if level == k else "")
            share = 100 * counts[level] / len(n)
            handles.append(Patch(fc=colour, label=f"target covered by {who} ({share:.1f} %)"))
    elif len(n):
        if n.any() and result.sensors:
            handles.append(
                Patch(fc=covered_colour(), ec=TARGET_EDGE, lw=0.9,
                      label="target covered by a sensor")
            )  # fmt: skip
        gaps = int(np.count_nonzero(n == 0))
        handles.append(
            Patch(fc=UNCOVERED, label=f"target not covered: {gaps * result.cell_m**2:,.0f} m²"
                  f" ({100 * gaps / len(n):.1f} %);\nlabels: the largest gaps")
        )  # fmt: skip
    for kind, fill, shapes in _footprints_by_colour(result):
        what = f"{kind} footprints" if kind else "sensor footprints"
        handles.append(
            Patch(fc=fill, alpha=FOOTPRINT_ALPHA, ec=FOOTPRINT_EDGE, lw=0.5,
                  label=f"{what} ({len(shapes)}): ground a\nsensor covers; overlaps darker")
        )  # fmt: skip
    if result.sensor_areas:
        count = len(result.sensor_areas)
        handles.append(
            Patch(fc=SENSOR_AREA_FILL, ec=SENSOR_AREA_EDGE, lw=1.0,
                  label=f"sensor area{'s' * (count != 1)}: where masts may stand ({count})")
        )  # fmt: skip
    if result.masts:
        handles.append(
            Line2D([], [], ls="none", marker="o", ms=11, mfc=MAST_FILL, mec="white",
                   label=f"masts ({len(result.masts)}), numbered as in\nsensors.csv")
        )  # fmt: skip
    if result.occluder_outlines:
        handles.append(
            Patch(fc=OCCLUDER_FILL, ec=OCCLUDER_EDGE, lw=0.5,
                  label="occluders: buildings, walls,\ntrees (top view)")
        )  # fmt: skip
    return handles

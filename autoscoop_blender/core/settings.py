"""Every knob of AutoSCOOP, defined once: its type, default, limits and help text.

A knob is a dataclass field whose metadata holds a ``Knob``. Everything else is
derived from these definitions:

* ``from_mapping`` reads a TOML table (unknown keys and wrong types are one-line
  errors naming the file and the key);
* ``validated`` checks every limit, whoever built the settings (file, panel, code);
* ``to_dict`` is what result.json and the checkpoint header record;
* the panel's properties (``props.py``) and the command-line options
  (``headless/cli.py``, one per knob, ``Setting.flag``) are generated from
  ``settings_schema``.

A new knob is one field here. Groups: ``CoverageSettings`` (how coverage is computed,
also for ``headless coverage``), ``ESParams`` (the paper's Table II and the mutation
widths), ``FitnessParams`` (Eq. 1-5), and ``OptimizeSettings``, which is
``CoverageSettings`` plus the optimizer's knobs with ``[es]`` and ``[fitness]`` as
nested tables.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Iterator, Mapping
from dataclasses import MISSING, asdict, dataclass, field, fields, is_dataclass, replace
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from .checks import brief
from .errors import InputError

T = TypeVar("T")

# Coverage methods and optimizers: (value, label, description), the panel's enum items.
METHODS = (
    ("targeted", "Targeted", "One sight ray per target point that can count (fast, exact)"),
    ("pointcloud", "Point cloud", "The paper's ray pattern and alpha shape (slow)"),
)
OPTIMIZERS = (
    ("es", "Evolution strategy", "The paper's: one sensor at a time, each by an ES"),
    ("greedy", "Greedy", "Set cover over positions x orientations: fewer sensors"),
    (
        "lp",
        "LP bound and plan",
        "Column generation for a proven lower bound, then LP rounding and local search",
    ),
)
OBJECTIVES = (
    ("cost", "Cost", "mast_cost per mast plus sensor_cost per sensor"),
    ("sensors", "Sensors", "The fewest sensors"),
    ("masts", "Masts", "The fewest masts (then the fewest sensors on them)"),
)
# Optimizers that work on the candidate set (positions x orientations).
CANDIDATE_OPTIMIZERS = ("greedy", "lp")

# tau of Eq. 2 below this is treated as zero (see ``FitnessParams.band_m``).
TAU_FLOOR = 0.05


@dataclass(frozen=True)
class Knob:
    """What a setting means and which values it takes.

    lo, hi: limits (None: open-ended); lo_open, hi_open: the limit itself is not
    allowed. choices: (value, label, description) of a string setting. flag: its
    command-line option where it is not the one derived from its path
    (``Setting.flag``). label: its name in the panel (None: not in the panel); soft:
    the panel slider's range, within the limits.
    """

    help: str
    lo: float | None = None
    lo_open: bool = False
    hi: float | None = None
    hi_open: bool = False
    choices: tuple[tuple[str, str, str], ...] = ()
    flag: str | None = None
    label: str | None = None
    soft: tuple[float, float] | None = None

    def limits_text(self) -> str:
        """The allowed range in words, e.g. "> 0", "in (0, 1]"."""
        if self.lo is not None and self.hi is not None:
            left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
            return f"in {left}{self.lo:g}, {self.hi:g}{right}"
        if self.lo is not None:
            return f"{'>' if self.lo_open else '>='} {self.lo:g}"
        if self.hi is not None:
            return f"{'<' if self.hi_open else '<='} {self.hi:g}"
        return "a finite number"

    def within(self, value: float) -> bool:
        """Whether a number is finite and within the limits."""
        try:
            if not math.isfinite(value):
                return False
        except OverflowError:  # an integer too large for a float
            return False
        if self.lo is not None and (value < self.lo or (self.lo_open and value == self.lo)):
            return False
        return self.hi is None or not (value > self.hi or (self.hi_open and value == self.hi))


def knob(default: Any, help: str, **meta: Any) -> Any:
    """A dataclass field that is a knob (see ``Knob`` for ``meta``)."""
    return field(default=default, metadata={"knob": Knob(help, **meta)})


@dataclass(frozen=True)
class Setting:
    """One knob of a settings class, found by ``settings_schema``.

    path: dotted name as in files ("rho", "es.mu"); kind: int, float, bool or str;
    optional: None is allowed (meaning "derive it").
    """

    path: str
    kind: type
    optional: bool
    default: Any
    knob: Knob

    @property
    def name(self) -> str:
        return self.path.rsplit(".", 1)[-1]

    @property
    def flag(self) -> str:
        """Its command-line option: the knob's own, else ``--`` and the path with dashes
        (``rho`` -> ``--rho``, ``es.sigma_xy_m`` -> ``--es-sigma-xy-m``)."""
        return self.knob.flag or "--" + self.path.replace(".", "-").replace("_", "-")

    @property
    def prop_name(self) -> str:
        """The panel property's name: the path with dots as underscores."""
        return self.path.replace(".", "_")

    def coerce(self, value: Any, label: str) -> Any:
        """``value`` as this setting's type, or InputError naming ``label`` and the key."""
        if value is None and self.optional:
            return None
        what = {int: "an integer", float: "a number", bool: "true or false", str: "a string"}
        if self.kind is bool:
            ok = isinstance(value, bool)
        elif self.kind is int:
            ok = isinstance(value, int) and not isinstance(value, bool)
        elif self.kind is float:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            if ok and isinstance(value, int) and not abs(value) <= 1e300:
                raise InputError(f"{label}: {self.path} is {brief(value)}, too large")
            value = float(value) if ok else value
        else:
            ok = isinstance(value, str)
        if not ok:
            raise InputError(f"{label}: {self.path} must be {what[self.kind]}, got {value!r}")
        return value

    def check(self, value: Any) -> None:
        """InputError when ``value`` (of the right type) is outside the limits."""
        if value is None and self.optional:
            return
        k = self.knob
        if k.choices:
            values = [c[0] for c in k.choices]
            if value not in values:
                raise InputError(f"{self.path} {value!r}: choose one of {', '.join(values)}")
            return
        if self.kind in (int, float) and not k.within(value):
            raise InputError(
                f"setting {self.path} ({self.flag}) = {value!r} is out of range: must be "
                f"{k.limits_text()}"
            )


def settings_schema(cls: type, prefix: str = "") -> Iterator[Setting]:
    """Every knob of a settings dataclass, nested groups flattened to dotted paths."""
    hints = typing.get_type_hints(cls)
    for f in fields(cls):
        hint = hints[f.name]
        if isinstance(hint, type) and is_dataclass(hint):
            yield from settings_schema(hint, f"{prefix}{f.name}.")
            continue
        meta = f.metadata.get("knob")
        if meta is None:
            continue
        args = typing.get_args(hint)
        optional = type(None) in args
        kind = next(a for a in args if a is not type(None)) if args else hint
        default = f.default if f.default is not MISSING else None
        yield Setting(prefix + f.name, kind, optional, default, meta)


def _key_text(key: Any) -> str:
    """A key as an error shows it: as written when plain, quoted when it holds odd
    characters (a line break would split the one-line message)."""
    text = str(key)
    return text if text.isidentifier() else repr(text)


def from_mapping(cls: type[T], data: Mapping[str, Any], label: str) -> T:
    """Settings of ``cls`` from a mapping (a TOML document): its defaults replaced by
    ``data``, nested groups as tables; InputError for unknown keys and wrong types,
    naming ``label`` (``validated`` then checks the limits)."""
    if not isinstance(data, Mapping):
        raise InputError(f"{label}: must be a table")
    hints = typing.get_type_hints(cls)
    by_name = {f.name: f for f in fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(data) - set(by_name))
    if unknown:
        raise InputError(f"{label}: unknown setting(s) {', '.join(_key_text(k) for k in unknown)}")
    schema = {s.name: s for s in settings_schema(cls) if "." not in s.path}
    values: dict[str, Any] = {}
    for key, value in data.items():
        if is_dataclass(hints[key]):
            values[key] = from_mapping(hints[key], value, f"{label} [{key}]")
        else:
            values[key] = schema[key].coerce(value, label)
    defaults: Any = cls()
    return replace(defaults, **values)


def flag_values(cls: type, options: Mapping[str, Any]) -> dict[str, Any]:
    """The values of ``cls``'s knobs from parsed command-line ``options`` keyed by the
    knobs' paths (argparse's ``vars(args)``); nested groups as dotted paths."""
    return {s.path: options[s.path] for s in settings_schema(cls)}


def with_values(settings: T, values: Mapping[str, Any]) -> T:
    """``settings`` with the knobs at dotted ``values`` paths replaced (``"rho"``,
    ``"es.mu"``); validated by the caller."""
    top: dict[str, Any] = {}
    nested: dict[str, dict[str, Any]] = {}
    for path, value in values.items():
        group, _, name = path.rpartition(".")
        if group:
            nested.setdefault(group, {})[name] = value
        else:
            top[path] = value
    for group, inner in nested.items():
        top[group] = with_values(getattr(settings, group), inner)
    return replace(settings, **top)  # type: ignore[type-var]


def check_all(settings: Any) -> None:
    """InputError for the first knob of ``settings`` that is out of range."""
    for s in settings_schema(type(settings)):
        value = settings
        for part in s.path.split("."):
            value = getattr(value, part)
        s.check(s.coerce(value, "settings"))


@dataclass(frozen=True)
class CoverageSettings:
    """How coverage is computed: method, target grid, the point-cloud knobs, and
    which sensors share a mast.

    Lengths in metres, densities in points per m^2 (XY projection).
    """

    method: str = knob(
        "targeted",
        "how a pose's coverage is computed",
        choices=METHODS,
        flag="--method",
        label="Coverage method",
    )
    grid_m: float = knob(
        1.0,
        "target grid spacing, m (each point stands for grid^2 of ground)",
        lo=0.0,
        lo_open=True,
        flag="--grid",
        label="Grid",
        soft=(0.05, 20.0),
    )
    target_height_m: float = knob(
        0.0,
        "height of the target points above the road, m (about 1 m: a vehicle)",
        lo=0.0,
        flag="--target-height",
    )
    min_density_per_m2: float | None = knob(
        None,
        "detection threshold, points/m^2, for every model (default: each model's own)",
        lo=0.0,
        flag="--min-density",
    )
    oversample: int | None = knob(
        None,
        "pointcloud: rays per pattern ray per axis (default: from spacing, range, grid)",
        lo=1,
        flag="--oversample",
    )
    alpha: float = knob(
        1.0,
        "pointcloud: alpha radius as a multiple of the local ray spacing",
        lo=0.0,
        lo_open=True,
        flag="--alpha",
    )
    alpha_m: float | None = knob(
        None, "pointcloud: a fixed alpha radius, m, instead of alpha", lo=0.0, lo_open=True
    )
    mast_join_m: float = knob(3.0, "sensors this close share a mast, m", lo=0.0)
    coverage_k: int = knob(
        1,
        "redundancy: sensors that must cover a target point for it to count (a target "
        "curve's coverage_k property overrides it for its area)",
        lo=1,
        hi=10,
        flag="--coverage-k",
        label="Coverage k",
        soft=(1, 10),
    )

    def validated(self: T) -> T:
        """Self, or InputError naming the first knob out of range."""
        check_all(self)
        return self

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class ESParams:
    """Population sizes and convergence (Table II), mutation widths and their decay
    (the paper is silent on these; see ``optimize/es.py``)."""

    mu: int = knob(40, "parents (Table II)", lo=1, label="Parents (mu)", soft=(1, 10_000))
    lam: int = knob(
        20, "offspring per epoch (Table II)", lo=1, label="Offspring (lambda)", soft=(1, 10_000)
    )
    eps: float = knob(
        0.2,
        "convergence: relative fitness spread of the parents (Table II)",
        lo=0.0,
        label="Convergence eps",
        soft=(0.0, 1.0),
    )
    max_epochs: int = knob(
        100, "epochs at most per sensor", lo=0, label="Max epochs", soft=(0, 100_000)
    )
    sigma_xy_m: float = knob(4.0, "offspring mutation width in x and y, m", lo=0.0)
    sigma_pitch_deg: float = knob(5.0, "offspring mutation width in pitch, deg", lo=0.0)
    sigma_yaw_deg: float = knob(30.0, "offspring mutation width in yaw, deg", lo=0.0)
    parent_sigma: float = knob(0.5, "parents' mutation widths relative to offspring", lo=0.0)
    decay: float = knob(
        0.93, "mutation widths shrink by this per epoch", lo=0.0, lo_open=True, hi=1.0
    )
    retries: int = knob(5, "halved steps tried when a mutation leaves the sensor areas", lo=0)

    def sigma(self, epoch: int) -> NDArray[np.float64]:
        """(4,) offspring mutation widths (x, y, pitch, yaw) in epoch ``epoch`` (1-based)."""
        s0 = np.array([self.sigma_xy_m, self.sigma_xy_m, self.sigma_pitch_deg, self.sigma_yaw_deg])
        return s0 * self.decay ** (epoch - 1)


@dataclass(frozen=True)
class FitnessParams:
    """Weights (Table II) and constants of the paper's fitness, Eq. 1-5."""

    w_ca: float = knob(1.0, "weight of coverage, Eq. 5 (Table II)", lo=0.0)
    w_ds: float = knob(0.5, "weight of closeness to fixed masts, Eq. 5 (Table II)", lo=0.0)
    w_sc: float = knob(2.5, "weight of seamless coverage, Eq. 5 (Table II)", lo=0.0)
    zeta: float = knob(0.02, "Eq. 1: value of a point covered already", lo=0.0)
    theta_tau_m: float = knob(
        2.0, "Eq. 2: decay length of footprint beside the targets, m", lo=0.0, lo_open=True
    )
    theta_m: float = knob(
        20.0, "Eq. 3 and 4: decay length of distances to fixed sensors, m", lo=0.0, lo_open=True
    )

    @property
    def band_m(self) -> float:
        """Outside cells farther than this from the targets have tau < TAU_FLOOR."""
        return self.theta_tau_m * math.sqrt(2.0 * math.log(1.0 / TAU_FLOOR))


@dataclass(frozen=True)
class OptimizeSettings(CoverageSettings):
    """Everything that decides an optimization's answer, with the scene, model, seed.

    position_step_m: lattice of mast positions (None: twice the grid spacing, 2 m by
    default: finer than a planner needs for a mast, coarse enough that the ES revisits
    positions and reuses their sight rays). max_sensors: a cap (None: none; the run
    still ends, since each sensor adds at least one target point).
    """

    optimizer: str = knob(
        "lp",
        "how the sensors are placed",
        choices=OPTIMIZERS,
        flag="--optimizer",
        label="Optimizer",
    )
    rho: float = knob(
        0.97,
        "coverage goal: fraction of the target points to cover, each to its k (the paper's rho)",
        lo=0.0,
        lo_open=True,
        hi=1.0,
        label="Coverage goal",
    )
    seed: int = knob(
        0,
        "es: random seed (same seed, same answer; lp and greedy draw nothing at random)",
        lo=0,
        hi=2**63 - 1,
        flag="--seed",
        label="Seed",
    )
    position_step_m: float | None = knob(
        None, "lattice of mast positions, m (default: twice the grid)", lo=0.0, lo_open=True
    )
    patience: int = knob(2, "es: searches in a row that add nothing before giving up", lo=1)
    max_sensors: int | None = knob(None, "stop at this many sensors (default: no cap)", lo=1)
    cache: bool = knob(True, "targeted: keep sight rays per mast position (same answers)")
    objective: str = knob(
        "cost", "what a plan minimizes", choices=OBJECTIVES, flag="--objective", label="Objective"
    )
    mast_cost: float = knob(
        3.0,
        "cost of a mast (foundation, power, fibre), in sensor units",
        lo=0.0,
        flag="--mast-cost",
    )
    sensor_cost: float = knob(
        1.0, "cost of a sensor (of a model in a pack without its own)", lo=0.0, flag="--sensor-cost"
    )
    max_sensors_per_mast: int = knob(
        4,
        "sensors one mast may carry, of any mix of models",
        lo=1,
        flag="--max-per-mast",
        label="Sensors per mast",
        soft=(1, 16),
    )
    bound: bool = knob(
        False,
        "also prove a lower bound on the objective over the candidate set (the lp optimizer "
        "always does)",
        flag="--bound",
    )
    tight_bound: bool = knob(
        False,
        "lp, a ground planned whole: the joint bound on masts and sensors with its site "
        "rows (a plan's masts alone see what it covers): a tighter proof for about three "
        "times the joint bound's time (on two_routes 72 instead of 71, in about 3 "
        "minutes more); give it a --time-limit long enough",
        flag="--tight-bound",
    )
    time_limit_s: float | None = knob(
        None,
        "lp: end the run after at most this many seconds with the best plan by then and "
        "its proven gap (default: 240 s for a ground planned whole; 210 s for each part of "
        "a ground planned in parts of up to 20,000 target points, at most 28 minutes in "
        "all unless that leaves a part under 120 s); a limit shorter than building the "
        "candidates takes ends once they are built: no plan exists without them",
        lo=0.0,
        lo_open=True,
        flag="--time-limit",
    )
    es: ESParams = field(default_factory=ESParams)
    fitness: FitnessParams = field(default_factory=FitnessParams)

    def validated(self) -> OptimizeSettings:
        check_all(self)
        if self.method != "targeted" and (self.optimizer in CANDIDATE_OPTIMIZERS or self.bound):
            what = (
                "a bound"
                if self.optimizer not in CANDIDATE_OPTIMIZERS
                else f"the {self.optimizer} optimizer"
            )
            raise InputError(f"{what} needs the targeted method")
        if self.objective != "sensors" and self.mast_cost == self.sensor_cost == 0:
            raise InputError("mast_cost and sensor_cost are both 0: nothing to minimize")
        return self

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], label: str) -> OptimizeSettings:
        """Settings from a config mapping (TOML): top-level keys plus [es] and
        [fitness] tables; see ``from_mapping``."""
        return from_mapping(cls, data, label).validated()


# The knobs shown in the Blender panel: those with a panel label.
PANEL_SETTINGS: tuple[Setting, ...] = tuple(
    s for s in settings_schema(OptimizeSettings) if s.knob.label is not None
)

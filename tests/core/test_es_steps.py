"""The ES's steps (``optimize/es.py``) with scripted randomness: a generator whose
every normal draw is its width and every integer draw its lowest value, so each
mutation, each halved retry and each epoch's population can be worked out by hand."""

from types import SimpleNamespace

import numpy as np
import pytest
import shapely

from autoscoop_blender.core.model.sensors import PAPER_CAMERA, SensorPose
from autoscoop_blender.core.optimize.es import EvolutionStrategy, SensorSearch, mutate, sample
from autoscoop_blender.core.problem import SearchSpace
from autoscoop_blender.core.settings import ESParams


class ScriptedRng:
    """Stands in for ``np.random.Generator``: ``normal`` draws its scale (a step of
    exactly one width), ``integers`` its lowest value; the widths asked for are kept."""

    def __init__(self):
        self.widths = []

    def normal(self, loc, scale, size=None):
        self.widths.append(np.array(scale, dtype=float).tolist())
        shape = np.shape(scale) if size is None else size
        return loc + np.broadcast_to(np.asarray(scale, dtype=float), shape).copy()

    def integers(self, low, high, size):
        return np.full(size, low, dtype=np.int64)


class Lattice:
    """A search space of the given lattice points (1 m apart), pitch 31 to 70."""

    pitch = (31.0, 70.0)

    def __init__(self, points):
        self.points = {tuple(map(float, p)) for p in points}

    def snap(self, x, y):
        return float(round(x)), float(round(y))

    def member(self, x, y):
        return (x, y) in self.points


def test_a_step_that_leaves_is_retried_at_half_the_width_then_dropped():
    """From (0, 0) with widths 8 m in x and 4 m in y: (8, 4) and (4, 2) are not
    positions, (2, 1) is: the third try lands. With one retry only, the position
    stays. Pitch 60 + 20 is clipped to 70, yaw 350 + 30 wraps to 20."""
    space = Lattice([(0, 0), (2, 1)])
    pop = np.array([[0.0, 0.0, 60.0, 350.0]])
    sigma = np.array([8.0, 4.0, 20.0, 30.0])
    rng = ScriptedRng()
    out = mutate(space, pop, sigma, 2, rng)
    assert out.tolist() == [[2.0, 1.0, 70.0, 20.0]]
    assert rng.widths == [[8.0, 4.0], [4.0, 2.0], [2.0, 1.0], 20.0, 30.0]
    assert pop.tolist() == [[0.0, 0.0, 60.0, 350.0]]  # a copy is mutated
    rng = ScriptedRng()
    assert mutate(space, pop, sigma, 1, rng).tolist() == [[0.0, 0.0, 70.0, 20.0]]
    assert rng.widths == [[8.0, 4.0], [4.0, 2.0], 20.0, 30.0]
    # A first step that lands is taken at once; pitch below its range is clipped up.
    rng = ScriptedRng()
    low = np.array([[0.0, 0.0, 40.0, 10.0]])
    out = mutate(Lattice([(4, 4)]), low, np.array([4.0, 4.0, -20.0, 30.0]), 2, rng)
    assert out.tolist() == [[4.0, 4.0, 31.0, 40.0]] and len(rng.widths) == 3


def test_each_individual_draws_its_own_steps():
    """With a real generator, 50 copies of one individual end up with 50 different
    pitches and yaws (one draw per individual, not one for all)."""
    space = SearchSpace([shapely.box(0, 0, 40, 40)], 1.0, 31.0, 70.0)
    pop = np.tile([20.0, 20.0, 50.0, 180.0], (50, 1))
    out = mutate(space, pop, np.array([2.0, 2.0, 5.0, 30.0]), 5, np.random.default_rng(4))
    assert len(np.unique(out[:, 2])) == 50 and len(np.unique(out[:, 3])) == 50
    assert len({(x, y) for x, y in out[:, :2]}) > 10


BOX = Lattice([(x, y) for x in range(21) for y in range(21)])
# mu = 2, lambda = 1, two epochs; widths (4 m, 4 m, 10 deg, 10 deg) halving each
# epoch, parents at half the offspring's.
SCRIPTED = ESParams(
    mu=2, lam=1, eps=0.0, max_epochs=2, sigma_xy_m=4.0, sigma_pitch_deg=10.0,
    sigma_yaw_deg=10.0, parent_sigma=0.5, decay=0.5, retries=0,
)  # fmt: skip


def _run(params, initial, fitness):
    """(search, populations evaluated, epochs yielded) of a scripted search."""
    pops = []

    def evaluate(pop):
        pops.append(pop.tolist())
        return [fitness(ind) for ind in pop]

    search = SensorSearch(BOX, params, ScriptedRng(), evaluate)
    epochs = list(search.steps(initial))
    return search, pops, epochs


def test_each_epoch_by_hand():
    """Fitness x. Epoch 1 (widths 4, 4, 10, 10): the child of parent 0 (the integer
    draw) moves by (4, 4, 10, 10), the parents by half that; the best two, x = 7 and
    4, are the next parents. Epoch 2 (widths halved): the child of (7, 2) lands at
    x = 9, the best."""
    initial = np.array([[0.0, 0.0, 40.0, 0.0], [5.0, 0.0, 40.0, 0.0]])
    search, pops, epochs = _run(SCRIPTED, initial, lambda ind: ind[0])
    assert pops == [
        [[0, 0, 40, 0], [5, 0, 40, 0]],
        [[2, 2, 45, 5], [7, 2, 45, 5], [4, 4, 50, 10]],
        [[8, 3, 47.5, 7.5], [5, 5, 52.5, 12.5], [9, 4, 50, 10]],
    ]
    assert epochs == [0, 0, 1, 1, 1, 2, 2, 2]
    assert search.best.tolist() == [9, 4, 50, 10] and search.best_fitness == 9
    assert (search.epochs, search.evaluations) == (2, 8)


def test_the_best_is_the_best_ever_seen():
    """The first epoch finds fitness 5; the second's best is 3: the answer stays the
    first epoch's first individual."""
    initial = np.array([[0.0, 0.0, 40.0, 0.0], [5.0, 0.0, 40.0, 0.0]])
    scores = iter([1, 2, 5, 0, 0, 3, 3, 3])
    search, pops, _ = _run(SCRIPTED, initial, lambda ind: next(scores))
    assert search.best.tolist() == pops[1][0] and search.best_fitness == 5


@pytest.mark.parametrize(
    "scores, epochs",
    [
        ([4, 4], 0),  # equal parents: converged at the start
        ([0, 0], 0),  # nothing to gain anywhere
        ([4, 3.3], 0),  # within eps = 0.2 of the best
        ([4, 3.1], 1),  # not within: an epoch, whose parents then all score 1
        ([5, 4], 0),  # exactly eps apart: converged
        ([1, 0.5], 1),  # a best of 1 or less still has a spread
    ],
)
def test_a_search_ends_when_its_parents_converge(scores, epochs):
    initial = np.array([[0.0, 0.0, 40.0, 0.0], [5.0, 0.0, 40.0, 0.0]])
    params = ESParams(**{**SCRIPTED.__dict__, "eps": 0.2})
    score = iter(scores + [1.0] * 6)
    search, pops, _ = _run(params, initial, lambda ind: next(score))
    assert search.epochs == epochs and len(pops) == 1 + epochs
    if scores[0] == scores[1]:  # a tie: the first one seen stays the best
        assert search.best.tolist() == initial[0].tolist()


def test_no_epoch_at_max_epochs_0_and_random_parents_by_default():
    params = ESParams(**{**SCRIPTED.__dict__, "max_epochs": 0})
    space = SearchSpace([shapely.box(0, 0, 4, 4)], 1.0, 31.0, 70.0)
    search = SensorSearch(space, params, np.random.default_rng(0), lambda p: [p[0][0]] * len(p))
    assert list(search.steps()) == [0, 0] and search.epochs == 0
    assert space.member(*search.best[:2])


def test_samples_lie_on_the_lattice_within_the_pitch_range():
    """5,000 samples of a 5 x 5 lattice: every position drawn, pitches over 31 to 70,
    yaws over the whole circle (one within 1 deg of 0: 1 - (359/360)^5000 ~ 1)."""
    space = SearchSpace([shapely.box(0, 0, 4, 4)], 1.0, 31.0, 70.0)
    pop = sample(space, 5000, np.random.default_rng(1))
    assert pop.shape == (5000, 4) and pop[:, 3].min() < 1.0
    assert all(space.member(x, y) for x, y in pop[:, :2])
    assert len({(x, y) for x, y in pop[:, :2]}) == 25  # every one of the 5 x 5 drawn
    assert pop[:, 2].min() >= 31.0 and pop[:, 2].max() <= 70.0 and np.ptp(pop[:, 2]) > 35
    assert pop[:, 3].min() >= 0.0 and pop[:, 3].max() < 360.0 and np.ptp(pop[:, 3]) > 340


class GapProblem:
    """What ``_gap_population`` reads: three positions on a 1 m lattice, (0, 0),
    (4, 0) and (5, 0) (only the first two on every 4th line); two target points at
    (0, 10, 0) and (10, 10, 0); a mast 6 m high; position (0, 0) reaches both points,
    (4, 0) point 1 and (5, 0) point 0."""

    reaches = {(0.0, 0.0): [0, 1], (4.0, 0.0): [1], (5.0, 0.0): [0]}

    def __init__(self, mu=3, points=((0.0, 10.0, 0.0), (10.0, 10.0, 0.0))):
        self.space = SearchSpace([shapely.box(0, 0, 5, 0.2)], 1.0, 31.0, 70.0)
        self.space.positions = np.array([(0.0, 0.0), (4.0, 0.0), (5.0, 0.0)])
        self.grid = SimpleNamespace(target_points=np.array(points))
        self.model = PAPER_CAMERA  # pitch 31 to 70 deg
        self.settings = SimpleNamespace(es=ESParams(mu=mu))
        self.probed = []

    def pose(self, x, y, pitch, yaw, model=0):
        return SensorPose(float(x), float(y), 6.0, 6.0, float(pitch), float(yaw))

    def reachable(self, pose, wanted):
        self.probed.append((pose.x, pose.y, pose.pitch_deg, pose.yaw_deg))
        return np.array([n for n in self.reaches[(pose.x, pose.y)] if wanted[n]], np.int64)


class ChoosingRng(ScriptedRng):
    """ScriptedRng that also chooses: always the likeliest (the first of those)."""

    def choice(self, n, size, p):
        self.p = np.asarray(p).tolist()
        return np.full(size, int(np.argmax(p)))


def _gaps(problem, wanted, coarse, rng=None):
    es = EvolutionStrategy()
    es.problem, es.rng = problem, rng or ChoosingRng()
    es.fixed = SimpleNamespace(short=np.array(wanted))
    return es._gap_population(coarse), es.rng


def test_the_restart_aims_at_the_gaps_each_position_sees():
    """Both points wanted: (0, 0) sees 2, (4, 0) one, (5, 0) one; drawn 2 : 1 : 1.
    From (0, 0, 6 m) their centroid (5, 10, 0) lies at yaw atan2(10, 5) = 63.43 deg
    and 6 m down over 11.18 m: pitch 28.22 deg; each individual gets one width more
    (5 deg, 15 deg), and the pitch is clipped to 31 .. 70."""
    problem = GapProblem()
    pop, rng = _gaps(problem, [True, True], coarse=False)
    assert rng.p == pytest.approx([0.5, 0.25, 0.25])
    yaw = np.degrees(np.arctan2(10.0, 5.0))
    pitch = np.degrees(np.arctan2(6.0, np.hypot(5.0, 10.0)))
    assert pitch == pytest.approx(28.22, abs=0.01) and yaw == pytest.approx(63.43, abs=0.01)
    assert pop.shape == (3, 4)
    assert pop[0] == pytest.approx([0.0, 0.0, max(31.0, pitch + 5.0), yaw + 15.0])
    assert rng.widths == [5.0, 15.0]
    # Each position was probed at the model's lowest pitch, looking along x.
    assert problem.probed == [(0.0, 0.0, 31.0, 0.0), (4.0, 0.0, 31.0, 0.0), (5.0, 0.0, 31.0, 0.0)]


def test_the_restart_probes_every_4th_line_when_coarse_and_gives_up_when_none_sees():
    """Only point 0 wanted: coarse, (0, 0) and (4, 0) are probed and only (0, 0) sees
    it (straight ahead, yaw 90); point 1 only: both see it, drawn 1 : 1, and from
    (0, 0) it lies at yaw 45, pitch 22.99 + 5, clipped to 31. Nothing wanted: no population."""
    problem = GapProblem()
    pop, rng = _gaps(problem, [True, False], coarse=True)
    assert [p[:2] for p in problem.probed] == [(0.0, 0.0), (4.0, 0.0)]
    assert rng.p == [1.0, 0.0]
    pitch = np.degrees(np.arctan2(6.0, 10.0)) + 5.0  # 30.96 deg, one width more
    assert pop[0] == pytest.approx([0.0, 0.0, pitch, 90.0 + 15.0])
    pop, rng = _gaps(GapProblem(), [False, True], coarse=True)
    assert rng.p == [0.5, 0.5] and pop[0] == pytest.approx([0.0, 0.0, 31.0, 45.0 + 15.0])
    assert _gaps(GapProblem(), [False, False], coarse=False)[0] is None


def test_the_restart_aims_south_and_steep_within_the_pitch_range():
    """Point 0 at (0, 1, 0), point 1 at (0, -10, 0): from (0, 0, 6 m) point 0 lies 80.5
    deg down (clipped to 70 with its 5 deg more); point 1 (seen from (4, 0) only,
    drawn second) at yaw 360 - atan2(10, 4) = 291.8 deg."""
    problem = GapProblem(points=((0.0, 1.0, 0.0), (0.0, -10.0, 0.0)))
    pop, _ = _gaps(problem, [True, False], coarse=False)
    assert pop[0] == pytest.approx([0.0, 0.0, 70.0, 90.0 + 15.0])
    pop, rng = _gaps(problem, [False, True], coarse=False)
    assert rng.p == [0.5, 0.5, 0.0]
    yaw = 360.0 - np.degrees(np.arctan2(10.0, 0.0))  # from (0, 0): due south
    assert pop[0][3] == pytest.approx((yaw + 15.0) % 360.0)
    gaps = GapProblem(points=((0.0, -10.0, 0.0), (0.0, -10.0, 0.0)))
    pop, _ = _gaps(gaps, [True, False], coarse=False)
    assert pop[0][3] == pytest.approx(270.0 + 15.0)
    # An aim at yaw 355 deg: its 15 deg more wrap round to 10.
    ahead = 10.0 * np.array([np.cos(np.radians(355.0)), np.sin(np.radians(355.0)), 0.0])
    pop, _ = _gaps(GapProblem(points=(ahead, ahead)), [True, False], coarse=False)
    assert pop[0][3] == pytest.approx(10.0)


def test_each_restarted_individual_draws_its_own_aim():
    """With a real generator, 12 individuals aimed at one point (56.3 deg down from
    (0, 0)) get 12 pitches and 12 yaws, spread about the aim (5 and 15 deg)."""
    problem = GapProblem(mu=12, points=((0.0, 4.0, 0.0), (10.0, 10.0, 0.0)))
    pop, _ = _gaps(problem, [True, False], coarse=False, rng=np.random.default_rng(3))
    assert len(np.unique(pop[:, 2])) == 12 and len(np.unique(pop[:, 3])) == 12
    assert np.all((pop[:, 2] >= 31.0) & (pop[:, 2] <= 70.0))

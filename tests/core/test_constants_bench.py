"""The verdicts of ``bench constants`` (worked by hand on made-up runs): the greedy's
best value per objective, and a zeta beating the default only beyond the seed spread."""

import argparse

from tools import constants_bench as cb


def _greedy(scene, value, got, objective="cost"):
    return {
        "scene": scene,
        "optimizer": "greedy",
        "constant": "mast_preference",
        "value": value,
        "objective": objective,
        "seed": 0,
        "objective_value": got,
    }


def _es(scene, zeta, seed, cost):
    return {
        "scene": scene,
        "optimizer": "es",
        "constant": "zeta",
        "value": zeta,
        "objective": "cost",
        "seed": seed,
        "cost": cost,
        "sensors": cost / 2,
        "masts": cost / 4,
    }


def test_the_greedy_value_best_on_every_scene_wins():
    runs = [
        *(_greedy("a", v, c) for v, c in ((0.0, 12), (0.5, 10), (1.0, 11))),
        *(_greedy("b", v, c) for v, c in ((0.0, 24), (0.5, 20), (1.0, 20))),
        _greedy("c", 0.0, 5),  # not every value ran here: left out
    ]
    s = cb.summary(runs)["greedy, cost"]
    assert s["scenes"] == ["a", "b"]
    assert s["winner"] == 0.5 and s["best_everywhere"] == [0.5]
    assert s["values"]["1"] == {"total": 31, "mean_vs_best": 1.05, "best_on": 1}


def test_a_zeta_beats_the_default_only_beyond_the_seed_spread():
    d = cb.DEFAULT_ZETA
    runs = [
        # a: 0.05 lower by 10 with sd 1; 0.1 lower by 1 within sd 1
        *(_es("a", d, s, c) for s, c in enumerate((100, 101, 99))),
        *(_es("a", 0.05, s, c) for s, c in enumerate((90, 91, 89))),
        *(_es("a", 0.1, s, c) for s, c in enumerate((99, 100, 98))),
        # b: 0.05 lower by 2, inside its own sd of ~5.3
        *(_es("b", d, s, c) for s, c in enumerate((50, 50, 50))),
        *(_es("b", 0.05, s, c) for s, c in enumerate((42, 52, 50))),
        *(_es("b", 0.1, s, c) for s, c in enumerate((50, 50, 50))),
    ]
    s = cb.summary(runs)["zeta"]
    assert s["seeds"] == 3
    assert s["scenes"]["a"]["0.05"] == {
        "seeds": 3,
        "mean": 90,
        "sd": 1.0,
        "min": 89,
        "max": 91,
        "sensors_mean": 45,
        "masts_mean": 22.5,
    }
    assert s["beats_default_on"] == {"0.05": ["a"], "0.1": []}
    assert "holds" in s["verdict"]


def test_the_plan_puts_the_greedy_first_and_the_es_seed_by_seed():
    args = argparse.Namespace(
        seed=5, seeds=2, preferences=(0.0, 1.0), objective_preferences=(), zetas=(0.02, 0.05)
    )
    plan = [(p.optimizer, p.value, p.objective, p.seed) for p in cb.plan(args)]
    assert plan == [
        ("greedy", 0.0, "cost", 5),
        ("greedy", 1.0, "cost", 5),
        ("es", 0.02, "cost", 5),
        ("es", 0.05, "cost", 5),
        ("es", 0.02, "cost", 6),
        ("es", 0.05, "cost", 6),
    ]

"""Singular-posture search over the joint box."""

from __future__ import annotations

import numpy as np
import pytest

from snake_pin import ParameterError, Snake, SnakeParams
from snake_pin.manipulability import manipulability
from snake_pin.singular import find_singular_postures


def test_found_postures_are_singular_by_pinocchio(table1: Snake) -> None:
    """Every family the search reports has R and D numerically zero by the Pinocchio route."""
    search = find_singular_postures(table1.params, starts=10, seed=1)
    assert search.families
    for fam in search.families:
        assert np.all(np.abs(fam.phi) <= np.pi / 2 + 1e-12)
        res = manipulability(table1, np.r_[0.3, -0.1, 0.4, fam.phi])
        assert res.R < 1e-9 * search.R_typical


def test_non_straight_family_has_free_first_joint(table1: Snake) -> None:
    """The non-straight sheet found for Table 1: phi_1 varies freely along it, R stays 0."""
    search = find_singular_postures(table1.params, starts=12, seed=2)
    fam = max(search.non_straight, key=lambda f: f.members)
    for shift in (-0.8, 0.5):
        phi = fam.phi.copy()
        phi[0] = np.clip(phi[0] + shift, -np.pi / 2, np.pi / 2)
        assert manipulability(table1, np.r_[0, 0, 0, phi]).R < 1e-9 * search.R_typical


def test_search_reports_minima_and_json(table1: Snake) -> None:
    """The JSON has postures and R of the same length; R values are below the threshold."""
    search = find_singular_postures(table1.params, starts=4, seed=3)
    data = search.to_dict()
    assert len(data["postures"]) == len(data["R"])
    assert all(r <= data["threshold"] for r in data["R"])
    assert len(search.minima_R) == 4


@pytest.mark.parametrize("kwargs", [{"starts": 0}, {"bound": 0.0}, {"bound": 4.0},
                                    {"free_joint": 10}])
def test_bad_settings(kwargs: dict) -> None:
    """Bad search settings are ParameterErrors."""
    with pytest.raises(ParameterError):
        find_singular_postures(SnakeParams.table1(), **kwargs)


def test_five_links_with_free_joint_is_always_singular() -> None:
    """n = 5 with a free joint: H12~ is 4 x 3, R~ = 0 everywhere; the search says so."""
    params = SnakeParams.table1(n=5)
    snake = Snake(params)
    rng = np.random.default_rng(0)
    for _ in range(5):
        assert manipulability(snake, np.r_[0, 0, 0, rng.uniform(-1, 1, 4)], free_joint=3).R == 0
    with pytest.raises(ParameterError, match="zero at every posture"):
        find_singular_postures(params, free_joint=3, starts=2)


def test_interrupted_search_keeps_the_starts_done(table1: Snake,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C during the third start: RunInterrupted whose partial search holds the two
    finished starts (the same minima as an uninterrupted search), marked interrupted."""
    import snake_pin.singular as singular
    from snake_pin.exceptions import RunInterrupted

    original, calls = singular.minimize, []

    def interrupted(*args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) == 5:  # two calls per start
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(singular, "minimize", interrupted)
    with pytest.raises(RunInterrupted, match="after 2 of 6 starts") as info:
        find_singular_postures(table1.params, starts=6, seed=4)
    partial = info.value.partial
    assert partial.status == "interrupted" and partial.starts == 2
    data = partial.to_dict()
    assert data["status"] == "interrupted" and data["starts_requested"] == 6
    monkeypatch.undo()
    whole = find_singular_postures(table1.params, starts=6, seed=4)
    assert np.allclose(partial.minima_phi, whole.minima_phi[:2])
    assert whole.status == "completed" and whole.to_dict()["starts_requested"] == 6


def test_interrupt_before_any_start_is_a_plain_interrupt(
        table1: Snake, monkeypatch: pytest.MonkeyPatch) -> None:
    """Nothing computed yet: the KeyboardInterrupt goes on as it is (no empty partial)."""
    import snake_pin.singular as singular
    from snake_pin.exceptions import RunInterrupted

    def interrupted(*args: object, **kwargs: object) -> object:
        raise KeyboardInterrupt

    monkeypatch.setattr(singular, "minimize", interrupted)
    with pytest.raises(KeyboardInterrupt) as info:
        find_singular_postures(table1.params, starts=3)
    assert not isinstance(info.value, RunInterrupted)


@pytest.mark.parametrize("kwargs", [{"starts": 10_001}, {"starts": 10**12}, {"starts": True},
                                    {"starts": 2.0}, {"seed": -1}, {"seed": 2**32},
                                    {"seed": 1.5}, {"bound": float("nan")}])
def test_limits(kwargs: dict) -> None:
    """starts in 1..MAX_STARTS, seed in 0..2**32-1, integers only, bound not NaN."""
    from snake_pin.singular import MAX_SEED, MAX_STARTS

    assert (MAX_STARTS, MAX_SEED) == (10_000, 2**32 - 1)
    with pytest.raises(ParameterError):
        find_singular_postures(SnakeParams.table1(), **kwargs)


def test_passive_joints_are_free_in_the_search() -> None:
    """A robot's passive joint is searched as a free joint (same minima as free_joint)."""
    passive = find_singular_postures(SnakeParams.table1(passive=(5,)), starts=2, seed=5)
    free = find_singular_postures(SnakeParams.table1(), starts=2, seed=5, free_joint=5)
    assert passive.free_joint == free.free_joint == 5
    assert np.allclose(passive.minima_R, free.minima_R)


def test_search_runs_with_one_blas_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every R evaluation of a search (the typical R and L-BFGS-B's objective) runs with
    BLAS/OpenMP limited to one thread; the limits are restored afterwards."""
    from threadpoolctl import threadpool_info

    import snake_pin.singular as singular

    seen: list[set[int]] = []
    batch = singular.r_batch

    def spy(*args: object, **kwargs: object) -> object:
        if len(seen) < 5:
            seen.append({pool["num_threads"] for pool in threadpool_info()})
        return batch(*args, **kwargs)

    before = [pool["num_threads"] for pool in threadpool_info()]
    monkeypatch.setattr(singular, "r_batch", spy)
    find_singular_postures(SnakeParams.table1(n=6), starts=1)
    assert len(seen) == 5 and all(threads == {1} for threads in seen)
    assert [pool["num_threads"] for pool in threadpool_info()] == before


@pytest.mark.parametrize("kwargs", [{"relative": float("nan")}, {"relative": "small"},
                                    {"progress": "yes"}, {"bound": None}, {"starts": 2.0},
                                    {"free_joint": [2.0]}])
def test_arguments_are_checked_before_the_search(kwargs: dict[str, object]) -> None:
    """Each bad argument is a ParameterError naming it, raised before any start runs."""
    name = next(iter(kwargs)).replace("_", " ")
    with pytest.raises(ParameterError, match=f"{name}|{name.replace(' ', '_')}"):
        find_singular_postures(SnakeParams.table1(n=5), **kwargs)  # type: ignore[arg-type]

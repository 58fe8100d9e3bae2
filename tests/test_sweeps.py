"""Posture sweeps (Figs. 2-9) and the (alpha, T_s) map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from snake_pin import ParameterError, Snake
from snake_pin.experiments.manipulability import write_sweep
from snake_pin.sweeps import MAX_POINTS, r_map, sweep


@pytest.mark.parametrize("family", ["arc", "alpha", "ts"])
@pytest.mark.parametrize("free_joint", [None, 5])
def test_zero_only_at_the_trivial_posture(table1: Snake, family: str,
                                          free_joint: int | None) -> None:
    """R (and D) vanish only at phi0 = 0, alpha = 0, T_s = 0 along each family (Figs. 2-9)."""
    sw = sweep(table1, family, free_joint=free_joint, points=41)
    trivial = 0.0
    assert np.array_equal(sw.zeros(), [trivial])
    assert np.all(sw.D[sw.values != trivial] > 0)


def test_arc_sweep_is_symmetric(table1: Snake) -> None:
    """Fig. 2 is symmetric in phi0 (mirror invariance)."""
    sw = sweep(table1, "arc", points=41)
    assert np.allclose(sw.R, sw.R[::-1], rtol=1e-8) and np.allclose(sw.D, sw.D[::-1], rtol=1e-6)


def test_free_joint_lowers_manipulability(table1: Snake) -> None:
    """Figs. 3 vs 2: with joint 5 free, R is smaller along the arcs (fewer inputs)."""
    full = sweep(table1, "arc", points=21)
    free = sweep(table1, "arc", free_joint=5, points=21)
    mask = full.values != 0
    assert np.all(free.R[mask] < full.R[mask])


def test_sweep_files(table1: Snake, tmp_path: Path) -> None:
    """write_sweep() produces CSV, JSON and PNG with the same numbers as rows()."""
    sw = sweep(table1, "ts", points=11)
    paths = write_sweep(sw, tmp_path)
    data = json.loads(paths["json"].read_text())
    assert np.allclose(data["R"], sw.R)
    lines = paths["csv"].read_text().splitlines()
    assert len(lines) == 12 and lines[0] == "T_s,D,R"
    assert np.allclose(np.loadtxt(lines[1:], delimiter=","), np.array(sw.rows()), rtol=1e-15)
    assert paths["png"].read_bytes()[:4] == b"\x89PNG"


def test_r_map_matches_sweeps(table1: Snake) -> None:
    """The batch map agrees with the per-posture sweep along alpha at T_s = 1.5."""
    rmap = r_map(table1, alpha_points=11, ts_points=5, ts_max=2.0)  # T_s = 0, .5, 1, 1.5, 2
    sw = sweep(table1, "alpha", points=11)
    assert np.allclose(rmap.R[3], sw.R, rtol=1e-9, atol=1e-15)
    assert np.all(rmap.R[0] == 0.0) or np.allclose(rmap.R[0], 0.0, atol=1e-15)


def test_unknown_family(table1: Snake) -> None:
    """An unknown family is a ParameterError naming the choices."""
    with pytest.raises(ParameterError, match="arc"):
        sweep(table1, "zigzag")


def test_interrupted_sweep_keeps_the_postures_done(table1: Snake, tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C in a sweep raises RunInterrupted whose partial sweep holds exactly the values
    computed before it, marked interrupted in its files."""
    import snake_pin.sweeps as sweeps
    from snake_pin.exceptions import RunInterrupted

    original, calls = sweeps.manipulability, []

    def interrupted(*args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(sweeps, "manipulability", interrupted)
    with pytest.raises(RunInterrupted, match="after 3 of 11") as info:
        sweep(table1, "ts", points=11)
    partial = info.value.partial
    assert partial.status == "interrupted" and len(partial.values) == len(partial.R) == 3
    monkeypatch.undo()
    assert np.allclose(partial.R, sweep(table1, "ts", points=11).R[:3], rtol=1e-12)
    data = json.loads(write_sweep(partial, tmp_path)["json"].read_text())
    assert data["status"] == "interrupted" and data["points_requested"] == 11


@pytest.mark.parametrize("points", [1, 0, MAX_POINTS + 1, 10**12, True, 2.5])
def test_points_outside_the_limit_are_refused(table1: Snake, points: object) -> None:
    """points must be an integer in 2..MAX_POINTS (no bool, no float, nothing allocated)."""
    with pytest.raises(ParameterError, match="points"):
        sweep(table1, "arc", points=points)  # type: ignore[arg-type]


def test_files_appear_together_or_not_at_all(table1: Snake, tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """If drawing the figure fails, neither the CSV nor the JSON is left behind."""
    import snake_pin.viz.plots as plots

    sw = sweep(table1, "arc", points=5)

    def broken(*args: object, **kwargs: object) -> None:
        raise RuntimeError("no figure")

    monkeypatch.setattr(plots, "plot_sweep", broken)
    with pytest.raises(RuntimeError):
        write_sweep(sw, tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_passive_joints_are_free_beside_the_free_joint(table1: Snake) -> None:
    """A passive joint and a free joint together give R~ with both joints free."""
    from snake_pin.manipulability import manipulability

    robot = Snake(table1.params.replace(passive=(5,)))
    sw = sweep(robot, "arc", free_joint=3, points=5)
    assert sw.stem == "sweep_arc_free3_5" and sw.to_dict()["free_joint"] == [3, 5]
    expected = [manipulability(table1, np.r_[0, 0, 0, np.full(9, v)], free_joint=(3, 5)).R
                for v in sw.values]
    assert np.allclose(sw.R, expected, rtol=1e-12)


def test_sweeps_and_maps_run_with_one_blas_thread(table1: Snake,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Inside a sweep and an R map every BLAS/OpenMP pool is limited to one thread; the
    limits are restored afterwards."""
    from threadpoolctl import threadpool_info

    import snake_pin.sweeps as sweeps

    seen: list[set[int]] = []
    single, batch = sweeps.manipulability, sweeps.manipulability_R_batch

    def spy(fn):
        def wrapped(*args: object, **kwargs: object) -> object:
            seen.append({pool["num_threads"] for pool in threadpool_info()})
            return fn(*args, **kwargs)
        return wrapped

    before = [pool["num_threads"] for pool in threadpool_info()]
    monkeypatch.setattr(sweeps, "manipulability", spy(single))
    monkeypatch.setattr(sweeps, "manipulability_R_batch", spy(batch))
    sweep(table1, "arc", points=3)
    r_map(table1, alpha_points=3, ts_points=3)
    assert len(seen) == 4 and all(threads == {1} for threads in seen)
    assert [pool["num_threads"] for pool in threadpool_info()] == before


@pytest.mark.parametrize(("points", "bounds", "count"), [
    (40, None, 41),             # even grid over -pi/5..pi/5: 0 inserted
    (41, None, 41),             # odd grid: its middle value is 0
    (9, (-0.3, 0.5), 9),        # a grid value of 5.6e-17: snapped to 0
    (4, (-0.3, 0.5), 5),        # -0.3, -0.033, 0.233, 0.5: 0 inserted
])
def test_the_singular_zero_is_always_swept(table1: Snake, points: int,
                                           bounds: tuple[float, float] | None,
                                           count: int) -> None:
    """An arc sweep whose range straddles 0 evaluates phi0 = 0 exactly (R = 0 there), in
    order, between the grid's own ends."""
    sw = sweep(table1, "arc", points=points, bounds=bounds)
    assert len(sw.values) == len(sw.R) == count and np.all(np.diff(sw.values) > 0)
    assert np.array_equal(sw.zeros(), [0.0]) and sw.R[sw.values == 0.0] == 0.0
    low, high = bounds or (-np.pi / 5, np.pi / 5)
    assert sw.values[0] == pytest.approx(low) and sw.values[-1] == pytest.approx(high)


def test_a_range_without_zero_is_swept_as_given(table1: Snake) -> None:
    """A range that does not hold 0: exactly ``points`` values from low to high, R > 0."""
    sw = sweep(table1, "arc", points=6, bounds=(0.1, 0.6))
    assert np.allclose(sw.values, np.linspace(0.1, 0.6, 6)) and np.all(sw.R > 0)

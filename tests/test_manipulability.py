"""Dynamic manipulability: paper definitions (30, 31, 42), invariances, Theorem 1, generic API."""

from __future__ import annotations

import example_robot_data as erd
import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from snake_pin import ParameterError, Serpenoid, Snake, SnakeParams, arc, paper, straight
from snake_pin.manipulability import (
    dynamic_manipulability,
    manipulability,
    manipulability_R_batch,
)


def _paper_criteria(params: SnakeParams, q: np.ndarray, free_joint: int | None = None):
    """D and R straight from the printed definitions: S of (33), blocks (22)/(41)."""
    h = paper.inertia_matrix(params, q)
    n = params.n
    if free_joint is not None:  # S = blockdiag(I3, S_sub), S_sub = [e_k e_1 .. e_{k-1} e_{k+1} ..]
        order = [free_joint - 1] + [i for i in range(n - 1) if i != free_joint - 1]
        sel = np.zeros((n + 2, n + 2))
        sel[:3, :3] = np.eye(3)
        sel[3:, 3:] = np.eye(n - 1)[:, order].T
        h = sel @ h @ sel.T  # eq. (36)
    m = 3 if free_joint is None else 4
    h11, h12, h22 = h[:m, :m], h[:m, m:], h[m:, m:]
    schur = h11 - h12 @ np.linalg.solve(h22, h12.T)
    a = np.linalg.solve(schur, h12 @ np.linalg.inv(h22))
    return np.linalg.svd(a, compute_uv=False), np.linalg.svd(h12, compute_uv=False)


@pytest.mark.parametrize("free_joint", [None, 5])
def test_matches_printed_definition(table1: Snake, rng: np.random.Generator,
                                    free_joint: int | None) -> None:
    """sigma and lambda equal the SVDs of (H11 - H12 H22^-1 H21)^-1 H12 H22^-1 and H12."""
    for _ in range(20):
        q = np.r_[rng.normal(size=3), rng.uniform(-1.5, 1.5, 9)]
        res = manipulability(table1, q, free_joint=free_joint)
        sigma, lam = _paper_criteria(table1.params, q, free_joint)
        assert np.allclose(res.sigma, sigma, rtol=1e-8)
        assert np.allclose(res.lambda_, lam, rtol=1e-10)
        assert res.D == res.sigma[-1] and res.R == res.lambda_[-1]


@pytest.mark.parametrize("free_joint", [None, 5])
def test_straight_posture_is_singular(table1: Snake, free_joint: int | None) -> None:
    """Section IV.1: D = R = 0 for phi = 0, with and without a free joint."""
    res = manipulability(table1, straight(10, theta_1=0.7), free_joint=free_joint)
    assert res.R == pytest.approx(0.0, abs=1e-14)
    assert res.D == pytest.approx(0.0, abs=1e-9 * res.sigma[0])


@pytest.mark.parametrize("free_joint", [None, 5])
def test_arcs_and_serpenoids_are_not_singular(table1: Snake, free_joint: int | None) -> None:
    """Sections IV.2-3: R > 0 on arcs (phi0 != 0) and serpenoids (alpha, T_s > 0)."""
    postures = [arc(10, x) for x in (-np.pi / 5, -0.2, 0.05, np.pi / 6)]
    postures += [Serpenoid(10, a, t).configuration()
                 for a, t in ((np.pi / 6, 1.5), (np.pi / 4, 1.0), (np.pi / 2, 2.0))]
    for q in postures:
        res = manipulability(table1, q, free_joint=free_joint)
        assert res.R > 1e-7 and res.D > 1e-7


@settings(max_examples=40, deadline=None)
@given(phi=st.lists(st.floats(-1.5, 1.5), min_size=9, max_size=9),
       x=st.floats(-5, 5), y=st.floats(-5, 5), theta=st.floats(-np.pi, np.pi))
def test_invariant_under_rigid_motion_and_mirror(phi: list[float], x: float, y: float,
                                                 theta: float) -> None:
    """D and R do not change with x_h, y_h, theta_1 (a rigid motion) nor under phi -> -phi."""
    snake = _TABLE1
    base = manipulability(snake, np.r_[0.0, 0.0, 0.0, phi])
    moved = manipulability(snake, np.r_[x, y, theta, phi])
    mirrored = manipulability(snake, np.r_[x, y, -theta, -np.asarray(phi)])
    for other in (moved, mirrored):
        assert np.allclose(other.sigma, base.sigma, rtol=1e-7, atol=1e-12)
        assert np.allclose(other.lambda_, base.lambda_, rtol=1e-9, atol=1e-14)


_TABLE1 = Snake(SnakeParams.table1())


def test_theorem1_d_zero_exactly_when_r_zero(table1: Snake, rng: np.random.Generator) -> None:
    """Theorem 1: D/D_typ and R/R_typ are both tiny or both not, on random and singular postures."""
    from snake_pin.singular import find_singular_postures

    search = find_singular_postures(table1.params, starts=12, seed=5)
    singular = [f.phi for f in search.families] + [np.zeros(9)]
    regular = [rng.uniform(-1.5, 1.5, 9) for _ in range(50)]
    typical = [manipulability(table1, np.r_[0, 0, 0, p]) for p in regular]
    d_typ = np.median([r.D for r in typical])
    r_typ = np.median([r.R for r in typical])
    for res in typical:
        assert res.D > 1e-6 * d_typ and res.R > 1e-6 * r_typ
    assert singular, "the search found no singular posture"
    for phi in singular:
        res = manipulability(table1, np.r_[0, 0, 0, phi])
        assert res.R < 1e-9 * r_typ and res.D < 1e-9 * d_typ


def test_heading_variant_splits_two_by_n(table1: Snake, rng: np.random.Generator) -> None:
    """heading=False uses H11 2x2, H12 2xn (end of III.1): two singular values each."""
    q = np.r_[0, 0, 0, rng.uniform(-1, 1, 9)]
    res = manipulability(table1, q, heading=False, blocks=True)
    assert res.blocks["H12"].shape == (2, 10) and res.sigma.shape == (2,)
    h = paper.inertia_matrix(table1.params, q)
    assert np.allclose(res.lambda_, np.linalg.svd(h[:2, 2:], compute_uv=False))


@pytest.mark.parametrize(("n", "free_joint"), [(3, None), (4, 2), (10, 0), (10, 10), (10, 2.5)])
def test_refuses_small_robots_and_bad_joints(n: int, free_joint: object) -> None:
    """n < 4 (n < 5 with a free joint) and joint indices outside 1..n-1 are ParameterErrors."""
    snake = Snake(SnakeParams.table1(n=n))
    with pytest.raises(ParameterError):
        manipulability(snake, np.zeros(n + 2), free_joint=free_joint)


def test_generic_api_equals_snake_api(table1: Snake, rng: np.random.Generator) -> None:
    """dynamic_manipulability with the unactuated w (and phi_5) equals manipulability."""
    for _ in range(10):
        q = np.r_[rng.normal(size=3), rng.uniform(-1.5, 1.5, 9)]
        for unactuated, free in (([0, 1, 2], None), ([0, 1, 2, 7], 5)):
            a = dynamic_manipulability(table1.model, table1.data, q, unactuated)
            b = manipulability(table1, q, free_joint=free)
            assert np.allclose(a.sigma, b.sigma, rtol=1e-9)
            assert np.allclose(a.lambda_, b.lambda_, rtol=1e-9)


def test_double_pendulum_acrobot(rng: np.random.Generator) -> None:
    """Acrobot (joint 1 passive): D = |H12| / (H11 H22 - H12^2), R = |H12|, closed by hand."""
    robot = erd.load("double_pendulum")
    model, data = robot.model, robot.model.createData()
    for _ in range(10):
        q = rng.uniform(-np.pi, np.pi, 2)
        res = dynamic_manipulability(model, data, q, unactuated=[0])
        m = pin.crba(model, data, q)
        h11, h12, h22 = m[0, 0], m[0, 1], m[1, 1]
        assert res.R == pytest.approx(abs(h12), rel=1e-12)
        # u'' = -(h11 - h12^2/h22)^-1 h12/h22 tau  =>  |gain| = |h12| / (h11 h22 - h12^2)
        assert res.D == pytest.approx(abs(h12) / (h11 * h22 - h12**2), rel=1e-9)


def test_ur5_reduces_to_yoshikawa(rng: np.random.Generator) -> None:
    """Fully actuated UR5: sigma are the singular values of J M^-1 (Yoshikawa)."""
    robot = erd.load("ur5")
    model, data = robot.model, robot.model.createData()
    frame = "tool0"
    for _ in range(5):
        q = pin.randomConfiguration(model)
        res = dynamic_manipulability(model, data, q, unactuated=[], task=frame)
        jac = pin.computeFrameJacobian(model, data, q, model.getFrameId(frame),
                                       pin.LOCAL_WORLD_ALIGNED)
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        direct = np.linalg.svd(jac @ np.linalg.inv(mass), compute_uv=False)
        assert np.allclose(res.sigma, direct, rtol=1e-8)
        # Yoshikawa's measure sqrt(det(J (M^T M)^-1 J^T)) is the product of the sigmas
        inv = np.linalg.inv(mass)
        measure = np.sqrt(np.linalg.det(jac @ inv @ inv.T @ jac.T))
        assert np.prod(res.sigma) == pytest.approx(measure, rel=1e-6)


def test_generic_api_bad_input(table1: Snake) -> None:
    """Unknown frame, out-of-range indices and wrong q size are clear errors."""
    from snake_pin import ConfigurationError

    with pytest.raises(ParameterError):
        dynamic_manipulability(table1.model, table1.data, np.zeros(12), [0, 99])
    with pytest.raises(ParameterError):
        dynamic_manipulability(table1.model, table1.data, np.zeros(12), [], task="nope")
    with pytest.raises(ConfigurationError):
        dynamic_manipulability(table1.model, table1.data, np.zeros(5), [0])


@pytest.mark.parametrize(("free_joint", "heading"), [(None, True), (5, True), (None, False)])
def test_batch_path_equals_single(table1: Snake, rng: np.random.Generator,
                                  free_joint: int | None, heading: bool) -> None:
    """manipulability_R_batch equals manipulability(...).R posture by posture."""
    phis = rng.uniform(-1.5, 1.5, (40, 9))
    batch = manipulability_R_batch(table1.params, phis, free_joint=free_joint, heading=heading)
    single = [manipulability(table1, np.r_[0, 0, 0, p], free_joint=free_joint,
                             heading=heading).R for p in phis]
    assert np.allclose(batch, single, rtol=1e-9, atol=1e-15)


def test_lateral_constraint_criterion_vanishes_at_arcs(table1: Snake) -> None:
    """Fig. 15: with no side slip on links 2..n, arcs are singular (criterion ~ 0), R is not."""
    from snake_pin.manipulability import lateral_constraint_manipulability

    for phi0 in (-np.pi / 5, -0.2, 0.3, np.pi / 6):
        q = arc(10, phi0, theta_1=0.4)
        lateral = lateral_constraint_manipulability(table1, q)
        assert lateral.D < 1e-9 * lateral.sigma[0]
        assert manipulability(table1, q).R > 1e-3
    for alpha, ts in ((np.pi / 4, 1.5), (np.pi / 6, 1.0)):
        q = Serpenoid(10, alpha, ts).configuration()
        lateral = lateral_constraint_manipulability(table1, q)
        assert lateral.D > 1e-4 * lateral.sigma[0]


def test_batch_r_keeps_passive_joints_free_like_the_single_route() -> None:
    """R~ batch with a passive joint equals manipulability() (passive joints are free)."""
    from snake_pin.manipulability import manipulability_R_batch

    params = SnakeParams.table1(passive=(5,))
    snake = Snake(params)
    rng = np.random.default_rng(3)
    phi = rng.uniform(-1.2, 1.2, (8, 9))
    batch = manipulability_R_batch(params, phi, free_joint=3)
    single = [manipulability(snake, np.r_[0.0, 0.0, 0.0, p], free_joint=3).R for p in phi]
    assert np.allclose(batch, single, rtol=1e-9)
    plain = manipulability_R_batch(SnakeParams.table1(), phi, free_joint=3)
    assert not np.allclose(batch, plain)


def test_package_name_stays_callable_after_the_submodule_is_imported() -> None:
    """`from snake_pin import manipulability` gives D, R even once snake_pin.sweeps is loaded."""
    import importlib

    import snake_pin

    importlib.import_module("snake_pin.sweeps")  # binds snake_pin.manipulability to the module
    from snake_pin import manipulability as by_name

    snake = Snake(SnakeParams.table1())
    q = np.r_[0.0, 0.0, 0.0, np.full(9, 0.3)]
    assert by_name(snake, q).R == pytest.approx(manipulability(snake, q).R, rel=1e-15)
    assert callable(snake_pin.manipulability)


@pytest.mark.parametrize("free_joint", [1.0, [2.0], (True,), "2", {2: 1}, np.array([2.5])])
def test_free_joints_are_integers(table1: Snake, free_joint: object) -> None:
    """A free joint given as a float, a bool, text or a mapping is refused, not rounded."""
    with pytest.raises(ParameterError, match=r"free.joint") as info:
        manipulability(table1, straight(10), free_joint=free_joint)  # type: ignore[arg-type]
    assert "\n" not in str(info.value)


def test_free_joints_accept_numpy_integers(table1: Snake) -> None:
    """NumPy integers (one or an array of them) are joint numbers like Python ints."""
    q = arc(10, 0.3)
    want = manipulability(table1, q, free_joint=(2, 5))
    for joints in (np.array([2, 5]), [np.int64(2), np.int32(5)]):
        assert manipulability(table1, q, free_joint=joints).R == want.R  # type: ignore[arg-type]
    assert manipulability(table1, q, free_joint=np.int64(5)).R == \
        manipulability(table1, q, free_joint=5).R


@pytest.mark.parametrize("flag", ["no", 0, None])
def test_heading_is_a_bool(table1: Snake, flag: object) -> None:
    """heading="no" would be truthy: anything but a bool is refused."""
    with pytest.raises(ParameterError, match="heading"):
        manipulability(table1, straight(10), heading=flag)  # type: ignore[arg-type]


def test_generic_api_refuses_float_indices_and_a_foreign_data(table1: Snake) -> None:
    """unactuated=[0.0, 1, 2] is refused (not truncated), and so is another model's data."""
    q = arc(10, 0.3)
    with pytest.raises(ParameterError, match="unactuated"):
        dynamic_manipulability(table1.model, table1.data, q, [0.0, 1, 2])
    other = Snake(SnakeParams.table1(n=5)).model.createData()
    with pytest.raises(ParameterError, match="data"):
        dynamic_manipulability(table1.model, other, q, [0, 1, 2])

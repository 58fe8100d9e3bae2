"""MuJoCo engine model for per-link robots: wheel pairs sized to each link, sparse solver."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from snake_pin import ParameterError, Snake, SnakeParams
from snake_pin.engine import WheelSpec, build_engine_model

from .conftest import heterogeneous_params

#: The engine robot with a camera head twice as long and three times as heavy, its CM
#: 40 % of the way back (yaw inertia of a uniform rod of that size, plus 20 %).
HEAVY_HEAD = SnakeParams.engine(
    link_length=[0.352] + [0.176] * 7, mass=[1.251] + [0.417] * 7,
    inertia=[1.2 * 1.251 * 0.352**2 / 12] + [1.2e-3] * 7, com_offset=[0.1408] + [0.088] * 7)


def _random_wheels(params: SnakeParams) -> WheelSpec:
    """Wheels small and light enough for every link of a random robot."""
    return WheelSpec(radius=0.2 * params.link_lengths.min(), mass=0.02 * params.masses.min(),
                     max_bend=0.5)


def _robots() -> list[tuple[str, SnakeParams, WheelSpec]]:
    random_robot = heterogeneous_params(np.random.default_rng(1), 10)
    return [("engine", SnakeParams.engine(), WheelSpec()),
            ("heavy_head", HEAVY_HEAD, WheelSpec()),
            ("random", random_robot, _random_wheels(random_robot))]


@pytest.mark.parametrize(("label", "params", "wheels"), _robots(),
                         ids=[r[0] for r in _robots()])
def test_chain_mass_matrix_equals_pinocchio(label: str, params: SnakeParams, wheels: WheelSpec,
                                            rng: np.random.Generator) -> None:
    """MuJoCo's mass matrix on (x, y, yaw, phi), wheels included, equals H to 1e-12."""
    engine = build_engine_model(params, wheels)
    snake = Snake(params)
    for _ in range(10):
        q = np.r_[rng.normal(size=2), rng.uniform(-3, 3), rng.uniform(-1.0, 1.0, params.n - 1)]
        engine.set_paper_configuration(q)
        assert np.allclose(engine.paper_configuration(), q, atol=1e-12)
        h = snake.inertia_matrix(q)
        assert np.abs(engine.chain_mass_matrix() - h).max() <= 1e-12 * np.abs(h).max()


def test_each_link_carries_its_own_mass_and_wheels_at_its_cm() -> None:
    """Link body + its two wheels weigh m_i, with the wheels at that link's CM offset."""
    engine = build_engine_model(HEAVY_HEAD)
    model = engine.model
    for i in range(HEAVY_HEAD.n):
        body = engine.link_bodies[i]
        wheels = [b for b in range(model.nbody) if model.body_parentid[b] == body
                  and model.body(b).name.startswith(f"link_{i + 1}_wheel")]
        assert len(wheels) == 2
        total = model.body_mass[body] + model.body_mass[wheels].sum()
        assert total == pytest.approx(HEAVY_HEAD.masses[i], rel=1e-14)
        assert model.body_pos[wheels, 0] == pytest.approx(HEAVY_HEAD.com_offsets[i])
        assert model.body_pos[wheels, 1] == pytest.approx(
            [engine.wheel_offsets[i], -engine.wheel_offsets[i]])
    # the long head's wheels stand further out than the others' (its capsule is thicker)
    assert engine.wheel_offsets[0] > engine.wheel_offsets[1] == engine.wheel_offsets[-1]


def test_uniform_accessors_refuse_per_link_robots() -> None:
    """body_mass, body_inertia, wheel_offset are one number only when the links are equal."""
    uniform = build_engine_model()
    assert uniform.body_mass == pytest.approx(0.417 - 2 * uniform.wheels.mass)
    engine = build_engine_model(HEAVY_HEAD)
    assert engine.body_masses[0] == pytest.approx(1.251 - 2 * engine.wheels.mass)
    for name in ("body_mass", "body_inertia", "wheel_offset"):
        with pytest.raises(ParameterError, match="differ"):
            getattr(engine, name)


def test_solver_uses_the_sparse_jacobian() -> None:
    """opt.jacobian is sparse, where MuJoCo's automatic choice would be dense (nv = 29)."""
    model = build_engine_model().model
    assert model.nv == 29
    assert model.opt.jacobian == mujoco.mjtJacobian.mjJAC_SPARSE and mujoco.mj_isSparse(model)
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_AUTO
    assert not mujoco.mj_isSparse(model)


def test_sparse_and_dense_give_the_same_step(rng: np.random.Generator) -> None:
    """One mj_step from a moving state gives the same velocities with either Jacobian."""
    engine = build_engine_model()
    q = np.r_[0.0, 0.0, np.pi, rng.uniform(-0.8, 0.8, 7)]
    out = []
    for jacobian in (mujoco.mjtJacobian.mjJAC_SPARSE, mujoco.mjtJacobian.mjJAC_DENSE):
        engine.model.opt.jacobian = jacobian
        engine.set_paper_configuration(q)
        for _ in range(20):  # settle onto the wheels under a torque
            engine.apply_torque(np.linspace(-1.0, 1.0, 7))
            mujoco.mj_step(engine.model, engine.data)
        out.append(engine.data.qvel.copy())
    assert engine.data.ncon > 0
    assert np.abs(out[0] - out[1]).max() <= 1e-9 * np.abs(out[1]).max()


@pytest.mark.parametrize(("changes", "wheels", "message"), [
    ({"mass": [0.417] * 7 + [0.05]}, WheelSpec(), "link 8: wheels of 0.03 kg"),
    ({"com_offset": [0.088] * 2 + [0.15, 0.03] + [0.088] * 4}, WheelSpec(),
     "links 3 and 4: wheels of radius 0.03 m overlap"),
    ({"link_length": [0.176] * 5 + [0.05] * 3}, WheelSpec(), "link 6: wheels of radius"),
])
def test_wheels_that_do_not_fit_a_link_are_refused(changes: dict, wheels: WheelSpec,
                                                   message: str) -> None:
    """Wheels too heavy, overlapping or longer than one link: ParameterError naming it."""
    with pytest.raises(ParameterError, match=message):
        build_engine_model(SnakeParams.engine(**changes), wheels)

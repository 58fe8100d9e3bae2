"""Robot parameters: the frozen, validated ``SnakeParams`` and its named presets (DESIGN §2)."""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass, field
from typing import Any

from ._validation import finite_number
from .exceptions import ParameterError

__all__ = ["ROBOTS", "SnakeParams"]


@dataclass(frozen=True)
class SnakeParams:
    """Parameters of an n-link planar snake robot with identical links.

    Parameters
    ----------
    n
        Number of links (>= 2).
    link_length
        Full link length 2l [m]; the paper's l is :attr:`half_length`.
    mass
        Link mass m [kg].
    inertia
        Link moment of inertia about its centre of mass, J [kg m^2].
    c_x, c_y
        Viscous friction along / across the link [N s/m] (eqs. 10-12).
    c_theta
        Rotational viscous friction [N m s] (eq. 13).
    passive
        1-based indices of joints without an actuator (free joints, Section III.2).
    name
        A label carried into file names and reports.
    """

    n: int = 10
    link_length: float = 0.12
    mass: float = 0.182
    inertia: float = 2.2e-4  # DESIGN §3 erratum 1: Table 1 prints 0.22 (g m^2)
    c_x: float = 0.5
    c_y: float = 0.5
    c_theta: float = 7.2e-5
    passive: tuple[int, ...] = field(default_factory=tuple)
    name: str = "table1"

    def __post_init__(self) -> None:
        if isinstance(self.n, bool) or not isinstance(self.n, numbers.Integral):
            raise ParameterError(f"n must be an integer, got {self.n!r}")
        if self.n < 2:
            raise ParameterError(f"n must be at least 2 links, got {self.n}")
        object.__setattr__(self, "n", int(self.n))
        for key in ("link_length", "mass", "inertia"):
            object.__setattr__(self, key, finite_number(getattr(self, key), key, positive=True))
        for key in ("c_x", "c_y", "c_theta"):
            object.__setattr__(self, key, finite_number(getattr(self, key), key, non_negative=True))
        try:
            passive = tuple(sorted({int(k) for k in self.passive}))
        except (TypeError, ValueError) as exc:
            raise ParameterError(f"passive must be joint indices, got {self.passive!r}") from exc
        for k in passive:
            if not 1 <= k <= self.n - 1:
                raise ParameterError(
                    f"passive joint {k} is outside 1..{self.n - 1} for a {self.n}-link snake")
        object.__setattr__(self, "passive", passive)
        if not isinstance(self.name, str) or not self.name.replace("_", "").isalnum():
            raise ParameterError(f"name must be alphanumeric (underscores allowed): {self.name!r}")

    # ----------------------------------------------------------------- derived
    @property
    def half_length(self) -> float:
        """The paper's l: half the link length [m]."""
        return 0.5 * self.link_length

    @property
    def body_length(self) -> float:
        """Total length n * 2l [m]."""
        return self.n * self.link_length

    @property
    def total_mass(self) -> float:
        """Total mass n * m [kg]."""
        return self.n * self.mass

    @property
    def actuated(self) -> tuple[int, ...]:
        """1-based indices of the actuated joints."""
        return tuple(k for k in range(1, self.n) if k not in self.passive)

    @property
    def isotropic(self) -> bool:
        """True when c_x == c_y (Section V: then g of eq. 67 is conserved)."""
        return self.c_x == self.c_y

    # ----------------------------------------------------------------- presets
    @classmethod
    def table1(cls, **changes: Any) -> SnakeParams:
        """The robot of Table 1 (Sections IV and VI.1), J in kg m^2 (erratum 1)."""
        return cls(**{"name": "table1", **changes})

    @classmethod
    def engine(cls, **changes: Any) -> SnakeParams:
        """The 8-link robot of Section VI.3 (2l = 0.176 m, m = 0.417 kg, J = 1.2e-3 kg m^2).

        Its viscous coefficients are the controller's model of the wheels; the engine
        experiment identifies them from the MuJoCo model.
        """
        base = {"name": "engine", "n": 8, "link_length": 0.176, "mass": 0.417,
                "inertia": 1.20e-3, "c_x": 0.5, "c_y": 5.0, "c_theta": 1.0e-4}
        return cls(**{**base, **changes})

    @classmethod
    def preset(cls, name: str, **changes: Any) -> SnakeParams:
        """A named preset from :data:`ROBOTS`."""
        if name not in ROBOTS:
            raise ParameterError(f"unknown robot {name!r}; choose one of {', '.join(ROBOTS)}")
        return getattr(cls, name)(**changes)

    def replace(self, **changes: Any) -> SnakeParams:
        """A validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-friendly dict of the fields."""
        d = dataclasses.asdict(self)
        d["passive"] = list(self.passive)
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SnakeParams:
        """Inverse of :meth:`to_dict` (validated)."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ParameterError(f"unknown parameter(s): {', '.join(sorted(unknown))}")
        return cls(**{**data, "passive": tuple(data.get("passive", ()))})


ROBOTS: tuple[str, ...] = ("table1", "engine")

"""Robot parameters: the frozen, validated ``SnakeParams`` and its named presets.

Every physical field is one number (all links alike) or one value per link, head first
(equal values collapse to the number, so two descriptions of one robot compare equal),
within its range of :data:`FIELD_RANGES` (:ref:`concepts`).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .exceptions import ParameterError

__all__ = ["FIELD_RANGES", "FRICTION_RANGE", "INERTIA_RANGE", "LENGTH_RANGE", "LINK_FIELDS",
           "MASS_RANGE", "MAX_LINKS", "ROBOTS", "PerLink", "SnakeParams"]

#: Largest number of links a robot may have (model, closed form and batch paths are
#: O(n^2) to O(n^3) in memory; 200 links keep every path well under 1 GiB).
MAX_LINKS = 200

#: A per-link value: one number for every link, or one number per link (head first).
PerLink = float | tuple[float, ...]

#: Per-link fields and whether 0 is allowed (friction may vanish, geometry and mass not).
LINK_FIELDS: dict[str, bool] = {
    "link_length": False, "mass": False, "inertia": False, "com_offset": True,
    "c_x": True, "c_y": True, "c_theta": True,
}

#: Link lengths 2l_i [m]: 0.1 mm to 100 m.
LENGTH_RANGE = (1e-4, 1e2)
#: Link masses m_i [kg]: 1 mg to 10 t.
MASS_RANGE = (1e-6, 1e4)
#: Yaw inertias J_i [kg m^2]: a 1 mg rod 0.1 mm long (8e-16) to a 10 t link 100 m long
#: (8e6), each end widened a little.
INERTIA_RANGE = (1e-16, 1e7)
#: Positive viscous friction coefficients: c_x, c_y [N s/m] and c_theta [N m s]; 0 is
#: also accepted (no friction), anything between 0 and the low end is not.
FRICTION_RANGE = (1e-12, 1e6)
#: The range of each per-link field that has one (com_offset lies in [0, 2l_i] instead).
FIELD_RANGES: dict[str, tuple[float, float]] = {
    "link_length": LENGTH_RANGE, "mass": MASS_RANGE, "inertia": INERTIA_RANGE,
    "c_x": FRICTION_RANGE, "c_y": FRICTION_RANGE, "c_theta": FRICTION_RANGE,
}
_UNITS = {"link_length": "m", "mass": "kg", "inertia": "kg m^2", "com_offset": "m",
          "c_x": "N s/m", "c_y": "N s/m", "c_theta": "N m s"}


def is_number(value: object) -> bool:
    """Whether ``value`` is a real number (a bool is not)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _per_link(value: object, key: str, n: int, *, zero_ok: bool) -> PerLink:
    """Validate a per-link field: a finite number or ``n`` finite numbers (collapsed if equal)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    scalar = is_number(value)
    if scalar:
        values: list[float] = [float(value)]  # type: ignore[arg-type]
    elif isinstance(value, Sequence) and not isinstance(value, (str, bytes)):
        if len(value) != n:
            raise ParameterError(
                f"{key} must be one number or {n} numbers (one per link), got {len(value)}")
        for i, item in enumerate(value, start=1):
            if not is_number(item):
                raise ParameterError(f"link {i}: {key} must be a number, got {item!r}")
        values = [float(item) for item in value]
    else:
        raise ParameterError(f"{key} must be a number or a list of {n} numbers, got {value!r}")
    for i, x in enumerate(values, start=1):
        where = f"{key}" if scalar else f"link {i}: {key}"
        if not math.isfinite(x):
            raise ParameterError(f"{where} must be finite, got {x}")
        if x < 0.0 or (x == 0.0 and not zero_ok):
            bound = "non-negative" if zero_ok else "positive"
            raise ParameterError(f"{where} must be {bound}, got {x:g}")
        low, high = FIELD_RANGES.get(key, (0.0, math.inf))
        if x != 0.0 and not low <= x <= high:
            zero = "0 or " if zero_ok else ""
            raise ParameterError(f"{where} must be {zero}in [{low:g}, {high:g}] {_UNITS[key]} "
                                 f"(physically meaningful), got {x:g}")
    if scalar or all(x == values[0] for x in values):
        return values[0]
    return tuple(values)


@dataclass(frozen=True)
class SnakeParams:
    """Parameters of an n-link planar snake robot (links numbered from the head).

    Parameters
    ----------
    n : int
        Number of links, ``2 <= n <= MAX_LINKS`` (:data:`MAX_LINKS`).
    link_length : float or sequence of n floats
        Full link length 2l_i [m] (joint i at x = 2l_i of link i), in :data:`LENGTH_RANGE`.
    mass : float or sequence of n floats
        Link mass m_i [kg], in :data:`MASS_RANGE`.
    inertia : float or sequence of n floats
        Link moment of inertia about its CM, J_i [kg m^2], in :data:`INERTIA_RANGE`.
    c_x, c_y, c_theta : float or sequence of n floats
        Viscous friction along / across link i [N s/m] and rotational [N m s] (eqs. 10-13),
        0 or in :data:`FRICTION_RANGE`.
    passive : sequence of int
        1-based indices (1..n - 1) of joints without an actuator (Section III.2).
    name : str
        A label for file names and reports (letters, digits, underscores); a preset's name
        on a robot with per-link values becomes ``NAME_custom``.
    com_offset : float or sequence of n floats or None
        Distance of link i's CM from its front end [m], in [0, 2l_i]; ``None``: l_i.

    Raises
    ------
    ParameterError
        Naming the field (and the link) out of its domain.
    """

    n: int = 10
    link_length: PerLink = 0.12
    mass: PerLink = 0.182
    inertia: PerLink = 2.2e-4  # erratum 1 (docs/errata.rst): Table 1 prints 0.22 (g m^2)
    c_x: PerLink = 0.5
    c_y: PerLink = 0.5
    c_theta: PerLink = 7.2e-5
    passive: tuple[int, ...] = field(default_factory=tuple)
    name: str = "table1"
    com_offset: PerLink | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.n, numbers.Integral) or isinstance(self.n, bool):
            raise ParameterError(f"n must be an integer, got {self.n!r}")
        if not 2 <= self.n <= MAX_LINKS:
            raise ParameterError(f"n must lie in 2..{MAX_LINKS} links, got {self.n}")
        n = int(self.n)
        object.__setattr__(self, "n", n)
        for key, zero_ok in LINK_FIELDS.items():
            value = getattr(self, key)
            if key == "com_offset" and value is None:
                continue
            object.__setattr__(self, key, _per_link(value, key, n, zero_ok=zero_ok))
        if self.com_offset is not None:
            offsets, lengths = self.per_link("com_offset"), self.link_lengths
            for i in np.flatnonzero(offsets > lengths):
                raise ParameterError(f"link {i + 1}: com_offset {offsets[i]:g} m lies beyond "
                                     f"the link's length {lengths[i]:g} m")
            if np.array_equal(offsets, 0.5 * lengths):
                object.__setattr__(self, "com_offset", None)
        object.__setattr__(self, "passive", self._check_passive(self.passive, n))
        if not isinstance(self.name, str) or not self.name.replace("_", "").isalnum():
            raise ParameterError(f"name must be alphanumeric (underscores allowed): {self.name!r}")
        if self.name in ROBOTS and not self.uniform:
            # per-link values make another robot: never call it by a preset's name
            object.__setattr__(self, "name", f"{self.name}_custom")

    @staticmethod
    def _check_passive(passive: object, n: int) -> tuple[int, ...]:
        if isinstance(passive, (str, bytes, Mapping)) or is_number(passive):
            raise ParameterError(f"passive must be a list of joint indices, got {passive!r}")
        try:
            items = list(passive)  # type: ignore[call-overload]
        except TypeError as exc:
            raise ParameterError(f"passive must be a list of joint indices, "
                                 f"got {passive!r}") from exc
        for k in items:
            if not isinstance(k, numbers.Integral) or isinstance(k, bool):
                raise ParameterError(f"passive joint indices must be integers, got {k!r}")
            if not 1 <= int(k) <= n - 1:
                raise ParameterError(
                    f"passive joint {k} is outside 1..{n - 1} for the {n}-link snake")
        return tuple(sorted({int(k) for k in items}))

    # ----------------------------------------------------------------- derived
    def per_link(self, key: str) -> np.ndarray:
        """Return the field ``key`` as an array of n values, head first.

        Parameters
        ----------
        key : str
            One of :data:`LINK_FIELDS`.

        Returns
        -------
        numpy.ndarray, shape (n,)
            A new array, in SI units; an unset ``com_offset`` gives l_i.

        Raises
        ------
        ParameterError
            If ``key`` is not a per-link field.
        """
        if key not in LINK_FIELDS:
            raise ParameterError(f"{key!r} is not a per-link field ({', '.join(LINK_FIELDS)})")
        value = getattr(self, key)
        if key == "com_offset" and value is None:
            return 0.5 * self.link_lengths
        return np.broadcast_to(np.asarray(value, dtype=float), (self.n,)).copy()

    @property
    def uniform(self) -> bool:
        """True when every link is alike (the paper's robots)."""
        return self.com_offset is None and all(
            not isinstance(getattr(self, key), tuple) for key in LINK_FIELDS)

    @property
    def link_lengths(self) -> np.ndarray:
        """2l_i of every link [m], head first."""
        return self.per_link("link_length")

    @property
    def masses(self) -> np.ndarray:
        """m_i of every link [kg]."""
        return self.per_link("mass")

    @property
    def inertias(self) -> np.ndarray:
        """J_i of every link about its centre of mass [kg m^2]."""
        return self.per_link("inertia")

    @property
    def com_offsets(self) -> np.ndarray:
        """Distance of every link's centre of mass from its front end [m]."""
        return self.per_link("com_offset")

    @property
    def half_length(self) -> float:
        """The paper's l (half the link length) [m]; uniform robots only.

        Raises
        ------
        ParameterError
            If the links have different lengths (use :attr:`link_lengths`).
        """
        if isinstance(self.link_length, tuple):
            raise ParameterError("half_length is defined for equal links only; "
                                 "use link_lengths / com_offsets")
        return 0.5 * float(self.link_length)

    @property
    def body_length(self) -> float:
        """Total length sum of 2l_i [m]."""
        if not isinstance(self.link_length, tuple):
            return self.n * float(self.link_length)
        return float(self.link_lengths.sum())

    @property
    def total_mass(self) -> float:
        """Total mass sum of m_i [kg]."""
        if not isinstance(self.mass, tuple):
            return self.n * float(self.mass)
        return float(self.masses.sum())

    @property
    def actuated(self) -> tuple[int, ...]:
        """1-based indices of the actuated joints."""
        return tuple(k for k in range(1, self.n) if k not in self.passive)

    @property
    def isotropic(self) -> bool:
        """True when c_x = c_y on every link (Section V: then g of eq. 67 is conserved)."""
        return bool(np.array_equal(self.per_link("c_x"), self.per_link("c_y")))

    # ----------------------------------------------------------------- presets
    @classmethod
    def table1(cls, **changes: Any) -> SnakeParams:
        """Return the robot of Table 1 (Sections IV and VI.1; the class's defaults).

        Parameters
        ----------
        **changes
            Fields to change from the preset.

        Returns
        -------
        SnakeParams
            The robot.
        """
        return cls(**{"name": "table1", **changes})

    @classmethod
    def engine(cls, **changes: Any) -> SnakeParams:
        """Return the 8-link wheeled robot of Section VI.3 (friction identified from MuJoCo).

        Parameters
        ----------
        **changes
            Fields to change from the preset.

        Returns
        -------
        SnakeParams
            The robot.
        """
        return cls(**{"name": "engine", "n": 8, "link_length": 0.176, "mass": 0.417,
                      "inertia": 1.20e-3, "c_x": 0.5, "c_y": 5.0, "c_theta": 1.0e-4, **changes})

    @classmethod
    def preset(cls, name: str, **changes: Any) -> SnakeParams:
        """Return a named preset from :data:`ROBOTS`.

        Parameters
        ----------
        name : str
            ``"table1"`` or ``"engine"``.
        **changes
            Fields to change from the preset.

        Returns
        -------
        SnakeParams
            The robot.

        Raises
        ------
        ParameterError
            If ``name`` is no preset, or a change is out of its domain.
        """
        if name not in ROBOTS:
            raise ParameterError(f"unknown robot {name!r}; choose one of {', '.join(ROBOTS)}")
        return getattr(cls, name)(**changes)

    def replace(self, **changes: Any) -> SnakeParams:
        """Return a validated copy with some fields changed.

        Parameters
        ----------
        **changes
            Field name -> new value (any field of :class:`SnakeParams`).

        Returns
        -------
        SnakeParams
            A new, validated instance.

        Raises
        ------
        ParameterError
            A name is not a field, or a new value is out of its domain.
        """
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise ParameterError(f"unknown parameter(s): {', '.join(sorted(unknown))}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Return the fields as a plain JSON-friendly dict (per-link fields as lists).

        Returns
        -------
        dict of str to object
            Field name -> value; :meth:`from_dict` reads it back into an equal instance.
        """
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SnakeParams:
        """Build a validated instance from a dict: the inverse of :meth:`to_dict`.

        Parameters
        ----------
        data : dict of str to object
            Field name -> value; missing fields take their defaults.

        Returns
        -------
        SnakeParams
            The validated robot.

        Raises
        ------
        ParameterError
            ``data`` is not a dict, names an unknown field, or a value is out of domain.
        """
        if not isinstance(data, dict):
            raise ParameterError(f"robot parameters must be a table, got {type(data).__name__}")
        return cls().replace(**data)  # the defaults with ``data``'s fields, checked by name


ROBOTS: tuple[str, ...] = ("table1", "engine")

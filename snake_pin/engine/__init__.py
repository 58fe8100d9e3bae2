"""The physics-engine check of Section VI.3 on MuJoCo: wheels, Coulomb contacts, closed loop."""

from .model import EngineModel, WheelSpec, build_engine_model

__all__ = ["EngineModel", "WheelSpec", "build_engine_model"]

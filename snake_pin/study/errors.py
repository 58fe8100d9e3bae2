"""The study's error, re-exported: :class:`snake_pin.exceptions.StudyError` (exit 2)."""

from __future__ import annotations

from ..exceptions import StudyError

__all__ = ["StudyError"]

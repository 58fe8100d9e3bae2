"""The study's error, re-exported: :class:`snake_pin.exceptions.StudyError`.

It derives from :class:`snake_pin.exceptions.SnakePinError`, so the command line reports
it as one line with exit status 2.
"""

from __future__ import annotations

from ..exceptions import StudyError

__all__ = ["StudyError"]

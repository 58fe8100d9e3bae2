"""The study's error: a study file, output folder or scheduler that cannot be used.

:class:`StudyError` derives from :class:`snake_pin.exceptions.SnakePinError`, so the
command line reports it as one line with exit status 2. (It lives here until the lead
moves it into :mod:`snake_pin.exceptions`; import it from :mod:`snake_pin.study`.)
"""

from __future__ import annotations

from ..exceptions import SnakePinError

__all__ = ["StudyError"]


class StudyError(SnakePinError, ValueError):
    """A study file, its output folder or the scheduler address is not usable (one line)."""

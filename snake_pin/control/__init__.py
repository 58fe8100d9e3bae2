"""Head-trajectory controllers sharing the interface of :class:`Controller`."""

from .base import Controller, OpenLoop

__all__ = ["Controller", "OpenLoop"]

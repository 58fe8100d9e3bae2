"""What one invocation of a study reports: :class:`StudySummary` (``summary.json``, ``--json``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .._json import json_safe

__all__ = ["StudySummary"]


@dataclass
class StudySummary:
    """The state of a study folder after one invocation.

    Parameters
    ----------
    name, study_hash, folder
        The study and where its results are.
    status
        ``complete``, ``interrupted`` or ``incomplete`` (runs lost with a dead worker).
    runs, recorded, ran, skipped, lost
        Runs in the study, recorded, recorded by this invocation or before it, and submitted
        by it but not recorded (a re-run executes them).
    statuses
        Recorded rows per status (``ok``, ``diverged``, ``failed``).
    wall_time, scheduler
        Seconds this invocation took; ``local (N workers)`` or the address given.
    files, note
        ``index.html``, ``summary.json``, the dataset and ``study.json``; why it stopped.
    """

    name: str
    study_hash: str
    folder: str
    status: str = "complete"
    runs: int = 0
    recorded: int = 0
    ran: int = 0
    skipped: int = 0
    lost: int = 0
    statuses: dict[str, int] = field(default_factory=dict)
    wall_time: float = 0.0
    scheduler: str = ""
    files: dict[str, str] = field(default_factory=dict)
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """Every field as plain RFC 8259 JSON data.

        Returns
        -------
        dict
            Non-finite numbers become None (null).
        """
        return dict(json_safe(self))

    def text(self) -> str:
        """A few lines for a terminal.

        Returns
        -------
        str
            Status, counts, time, where the results are, and the note.
        """
        counts = ", ".join(f"{v} {k}" for k, v in self.statuses.items() if v)
        lines = [f"study {self.name}: {self.status}, {self.recorded}/{self.runs} runs recorded"
                 f" ({counts or 'none'}); ran {self.ran}, skipped {self.skipped}"
                 + (f", lost {self.lost}" if self.lost else "")
                 + f" in {self.wall_time:.1f} s on {self.scheduler}"]
        if self.note:
            lines.append(self.note)
        lines += [f"{k}: {v}" for k, v in self.files.items()]
        return "\n".join(lines)


"""What one invocation of a study reports: :class:`StudySummary` (``summary.json``, ``--json``)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

__all__ = ["StudySummary"]


@dataclass
class StudySummary:
    """The state of a study folder after one invocation.

    Parameters
    ----------
    name, study_hash, folder
        The study and where its results are.
    status
        ``complete``, ``interrupted`` (the batches written so far are kept) or
        ``incomplete`` (some runs lost with a dead worker; re-run to retry them).
    runs, recorded, ran, skipped
        Runs in the study, with a row in the dataset, executed and recorded by this
        invocation, and already recorded when it started.
    lost
        Runs this invocation submitted and did not record; a re-run executes them.
    statuses
        Recorded rows per status (``ok``, ``diverged``, ``failed``).
    wall_time
        Seconds this invocation took, cluster start included.
    scheduler
        ``local (N workers)`` or the address given.
    files
        ``index.html``, ``summary.json``, the dataset folder and ``study.json``.
    note
        One line: why it stopped, if it did.
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
        """Plain RFC 8259 JSON data.

        Returns
        -------
        dict
            Every field; non-finite numbers become None (null).
        """
        return _finite(asdict(self))

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


def _finite(value: Any) -> Any:
    """``value`` with non-finite floats as None (the fields are plain numbers and text)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value

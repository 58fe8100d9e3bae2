"""Studies: many closed-loop runs described by one file, run on Dask, kept in Parquet.

- :mod:`~snake_pin.study.spec`: the study file (base scenario, axes), validation, run keys;
- :mod:`~snake_pin.study.work`: the unit of work (one run -> its result row);
- :mod:`~snake_pin.study.runner`: execution on a Dask cluster (TLS-authenticated locally;
  a given scheduler checked by Dask's handshake on a deadline), resuming, interrupts;
- :mod:`~snake_pin.study.results`: the output folder and its Parquet dataset;
- :mod:`~snake_pin.study.summary`, :mod:`~snake_pin.study.report`: the summary and the page;
- :mod:`~snake_pin.study.command`: the ``snake-pin study`` subcommand.
"""

from .command import add_study_parser as add_study_parser  # the CLI's, not in __all__
from .errors import StudyError
from .runner import run_study
from .spec import SETTINGS, Scenario, StudySpec, load_study, run_key
from .summary import StudySummary

__all__ = ["SETTINGS", "Scenario", "StudyError", "StudySpec", "StudySummary", "load_study",
           "run_key", "run_study"]

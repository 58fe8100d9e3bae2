"""Studies: many closed-loop runs described by one file (:mod:`~snake_pin.study.spec`), one
per Dask task (:mod:`~snake_pin.study.work`, :mod:`~snake_pin.study.runner`), kept in Parquet
(:mod:`~snake_pin.study.results`) with a summary and a page; :ref:`studies`.
"""

from .errors import StudyError
from .runner import run_study
from .spec import SETTINGS, Scenario, StudySpec, load_study, run_key
from .summary import StudySummary

__all__ = ["SETTINGS", "Scenario", "StudyError", "StudySpec", "StudySummary", "load_study",
           "run_key", "run_study"]

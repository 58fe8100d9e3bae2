"""Studies: many closed-loop runs described by one file (:mod:`~snake_pin.study.spec`), run
on Dask (``runner``, ``work``; TLS-authenticated locally), kept in Parquet (``results``) with
their summary and page (``summary``, ``report``); ``snake-pin study`` runs one.
"""

from .errors import StudyError
from .runner import run_study
from .spec import SETTINGS, Scenario, StudySpec, load_study, run_key
from .summary import StudySummary

__all__ = ["SETTINGS", "Scenario", "StudyError", "StudySpec", "StudySummary", "load_study",
           "run_key", "run_study"]

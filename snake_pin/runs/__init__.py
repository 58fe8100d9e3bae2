"""The runs that ``snake-pin`` and the report share, below both (tracking, PFL, the engine
runs, the benchmark on paths, analysis outputs, and jobs on the one Dask executor: see
:doc:`/architecture`); nothing here imports the command line or the report stages.
"""

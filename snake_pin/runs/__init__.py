"""The runs that ``snake-pin`` and the report share, below both.

:mod:`~snake_pin.runs.tracking` (the Lyapunov-like head tracking of VI.2),
:mod:`~snake_pin.runs.pfl` (the PFL run of VI.1), :mod:`~snake_pin.runs.engine` (the
MuJoCo runs of VI.3 as distributions over perturbed starts),
:mod:`~snake_pin.runs.benchmark` (the path metrics and the controller benchmark on
paths), :mod:`~snake_pin.runs.outputs` (a robot's facts, the files of a sweep and of a
singular-posture search) and :mod:`~snake_pin.runs.parallel` (independent jobs on the
package's one Dask executor). The report stages (:mod:`snake_pin.experiments`) and the
command line call these; nothing here imports either.
"""

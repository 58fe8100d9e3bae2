"""
Run a small study and read its results with pandas
==================================================

A **study** is many closed-loop runs described by one TOML file: a base scenario and
axes over its settings (grids, seeded random draws). :func:`snake_pin.study.run_study`
runs the runs not yet recorded on a Dask cluster, one Parquet file per finished run,
and writes a summary and a page; the command line is ``snake-pin study FILE -o DIR``.

Here: the Lyapunov-like controller on the Table 1 robot with wheel-like friction, two
values of the head's decay rate ``lam`` against three noisy initial postures, 4 s each.
By default a study starts worker processes (a script that calls ``run_study`` then needs
the usual ``if __name__ == "__main__":`` guard); this example hands it an in-process
cluster on 127.0.0.1 instead, through the same ``scheduler`` and ``security`` arguments
that take a remote cluster's address and credentials. A Dask cluster without TLS lets
any local user connect and run code as you: this one speaks TLS with credentials made
for it (``security=True``), and ``run_study`` connects with them
(``security=cluster.security``); ``snake-pin study --scheduler tls://... --security
FILE`` does the same from the command line.
"""

# %%
# The study file
# --------------
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from distributed import LocalCluster

from snake_pin.study import load_study, run_study

folder = Path(tempfile.mkdtemp())
study_file = folder / "gains.toml"
study_file.write_text("""
[study]
name = "gallery_gains"

[base]
robot = "table1"
controller = "lyapunov"
model = "viscous"
t_final = 4.0
error_window = 2.0         # head errors are judged over t >= 2 s
c_x = 0.5
c_y = 25.0
init_noise = 0.05          # Gaussian noise on each initial joint angle [rad]

[axes.lam]                 # grid axis
values = [3.0, 10.0]

[axes.init_seed]           # replicates: one noise realisation each
values = [1, 2, 3]
""")
spec = load_study(study_file)   # validated whole before anything runs
print(spec.name, "-", len(spec.scenarios), "runs over", [axis.setting for axis in spec.axes])

# %%
# Run it, then run it again
# -------------------------
# Results are keyed by each run's settings: the second invocation finds every run
# recorded and runs nothing.
out = folder / "results"
with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tls",
                  security=True, host="127.0.0.1", dashboard_address=None,
                  scheduler_kwargs={"dashboard": False}) as cluster:
    assert cluster.scheduler_address.startswith("tls://")
    first = run_study(study_file, out, scheduler=cluster.scheduler_address,
                      security=cluster.security, progress=False)
    again = run_study(study_file, out, scheduler=cluster.scheduler_address,
                      security=cluster.security, progress=False)
print(f"first: {first.status}, ran {first.ran}; again: ran {again.ran}, "
      f"skipped {again.skipped}")
assert first.status == "complete" and first.statuses["ok"] == first.runs
assert again.ran == 0 and again.skipped == first.runs

# %%
# Read the results with pandas
# ----------------------------
# One row per run: every setting, then the outcome (status, head errors in metres and
# in % of the body length, the smallest R and D along the run, ...).
runs = pd.read_parquet(out / "runs")
print(runs[["lam", "init_seed", "status", "rms_head_error_pct", "R_min"]]
      .sort_values(["lam", "init_seed"]).to_string(index=False))
by_rate = runs.groupby("lam")["rms_head_error_pct"].agg(["median", "min", "max"])
print(by_rate)

fig, ax = plt.subplots(figsize=(6, 3.6))
for lam, group in runs.groupby("lam"):
    ax.plot(group["init_seed"], group["rms_head_error_pct"], "o-", label=f"lam = {lam:g} /s")
ax.set_xlabel("initial-posture noise seed")
ax.set_ylabel("RMS head error [% of body length]")
ax.set_title("4 s runs of the Lyapunov-like law", fontsize=10)
ax.legend(fontsize=8)
fig.tight_layout()
plt.show()

# A faster decay of the head's error tracks better, whatever the initial noise.
assert by_rate.loc[10.0, "max"] < by_rate.loc[3.0, "min"]

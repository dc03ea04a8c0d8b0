"""The worked example of docs/redundant_imu.md: prints every number on that page and writes its
figures to docs/figures/ (run from the repository root: ``python docs/examples/redundant_imu.py``).

1. A simulated redundant array of 4 gyros (known truth) with the eq. 13 perturbation, a = 0, 5, 10:
   each combiner's error standard deviation against the truth (the shape of Table 4).
2. A GARCH(1,1) at the scale of Table 2, fitted as given (rad/s).
3. The two real ADIS16405 replicates of ../shared/data: one model from both (pooled GMWM) and the
   test of whether they share one.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import stochmod
from stochmod.data.redundant import redundant_gyros
from stochmod.io.recording import read_recording
from stochmod.core.tables import format_table

ROOT = Path(__file__).resolve().parents[2]
FIG = ROOT / "docs" / "figures"
DATA = ROOT / ".." / "shared" / "data" / "imudata"


def part1() -> None:
    rows, garch10 = [], None
    for a in (0, 5, 10):
        x, truth = redundant_gyros(a)
        row = [a]
        for name in ("mean", "averaged-volatility", "garch", "inverse-variance"):
            res = stochmod.combine(x, name)
            row.append(float(np.std(res.signal - truth)))
            if name == "garch" and a == 10:
                garch10 = (x, truth, res)
        rows.append(row)
    print(format_table(["a", "mean", "averaged-volatility", "garch", "inverse-variance"], rows,
                       title="error std of the synthetic signal [rad/s] (truth known)", digits=4))
    x, truth, res = garch10
    print(res.summary().split("\n\n")[0])
    print(res.sensors[0].summary())
    t = np.arange(x.shape[1]) / 100.0
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for i in range(4):
        top.plot(t, np.sqrt(res.sensor_variance[i]), lw=0.8, label=f"sensor {i}")
    top.plot(t, np.sqrt(res.variance), "k", lw=1.2, label="weighted synthetic")
    top.set_yscale("log")
    top.set_ylabel("GARCH volatility [rad/s]")
    top.legend(fontsize=8, ncol=5)
    top.set_title("GARCH-weighted synthetic IMU, eq. 13 perturbation a = 10 on sensor 0")
    for i in range(4):
        bottom.plot(t, res.weights[i], lw=0.8)
    bottom.set_ylabel("weight")
    bottom.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(FIG / "redundant_garch_weights.png", dpi=80)
    plt.close(fig)


def part2() -> None:
    omega, alpha, beta = 1.3e-7, 0.0175, 0.98
    z = np.random.default_rng(2010).standard_normal(305_000)
    x = np.empty(z.size)
    s2 = omega / (1 - alpha - beta)
    for k in range(z.size):
        x[k] = math.sqrt(s2) * z[k]
        s2 = omega + alpha * x[k] ** 2 + beta * s2
    fit = stochmod.fit_garch(x[5000:])
    print(fit.summary())


def part3() -> None:
    if not DATA.is_dir():
        print("../shared/data is absent: part 3 skipped")
        return
    xs, freq = [], None
    for k in (1, 2):
        rec = read_recording(DATA / f"adis_16405_imu{k}.npz", columns=["Gyro_X"])
        x = np.deg2rad(rec.column("Gyro_X"))
        xs.append(x - x.mean())
        freq = rec.freq
    pooled = stochmod.gmwm(xs, "2*GM+WN", freq)
    singles = [stochmod.gmwm(x, "2*GM+WN", freq) for x in xs]
    print(pooled.pooled.test.summary())
    print(pooled.summary())
    rows = [[name, *fit.model.vector(), *fit.std_errors] for name, fit in
            (("imu1", singles[0]), ("imu2", singles[1]), ("pooled", pooled))]
    names = list(pooled.free_names)
    print(format_table(["fit", *names, *(f"se {n}" for n in names)], rows, digits=4))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, rep in enumerate(pooled.pooled.replicates):
        ax.loglog(rep.tau, rep.wv, "o", ms=3, label=f"imu{k + 1} empirical")
    ax.loglog(pooled.empirical.tau, pooled.empirical.wv, "k.", label="pooled")
    ax.loglog(pooled.empirical.tau, pooled.model_wv(), "r-", label="pooled fit 2*GM+WN")
    ax.set_xlabel("tau [s]")
    ax.set_ylabel("Haar wavelet variance [(rad/s)^2]")
    ax.set_title(f"ADIS16405 Gyro_X replicates; equality test p = {pooled.pooled.test.pvalue:.3g}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(FIG / "adis16405_pooled_wv.png", dpi=80)
    plt.close(fig)


if __name__ == "__main__":
    FIG.mkdir(parents=True, exist_ok=True)
    part1()
    part2()
    part3()

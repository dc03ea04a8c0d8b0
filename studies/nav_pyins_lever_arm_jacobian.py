"""pyins 1.0.1's GNSS velocity measurement with a lever arm, checked in pyins' own terms.

``pyins.measurements.NedVelocity.compute_matrices`` predicts the antenna velocity ``v + C (w x
l)`` but takes its Jacobian from ``error_model.ned_velocity_error_jacobian(pva)`` without the
lever arm, although that function adds the lever-arm term when given it. This script builds,
with pyins' own error model (``InsErrorModel``: position error, the modified velocity error
``dv'``, the attitude error ``phi``; ``correct_pva`` inverts it), a state whose error is a known
small ``x``, evaluates pyins' measurement there and at the truth, and compares the change of
the innovation with ``H x`` for the Jacobian pyins uses and for the one with the lever arm, on
a car turning at 20 deg/s with the n380's lever arm, (-1.3, 0, 0) m
(docs/navigation_real_drive.md, "With velocity updates and the lever arm").

Run ``python studies/nav_pyins_lever_arm_jacobian.py``.
"""

from __future__ import annotations

import sys

import numpy as np


def main() -> int:
    import pandas as pd
    import pyins
    from pyins import transform
    from scipy.spatial.transform import Rotation

    arm = np.array([-1.3, 0.0, 0.0])
    model = pyins.error_model.InsErrorModel()
    truth = pd.Series({"lat": 45.0, "lon": -93.0, "alt": 250.0, "VN": 12.0, "VE": 5.0,
                       "VD": 0.1, "roll": 3.0, "pitch": -2.0, "heading": 40.0,
                       "rate_x": 0.01, "rate_y": -0.02, "rate_z": np.radians(20.0)})
    rng = np.random.default_rng(0)
    rows = []
    for _ in range(5):
        # a small error in pyins' internal states: dr (m), dv' (m/s), phi (rad)
        x = np.r_[rng.normal(0, 1e-3, 3), rng.normal(0, 1e-4, 3), rng.normal(0, 1e-4, 3)]
        rot = Rotation.from_rotvec(x[6:9]).as_matrix()
        estimate = truth.copy()
        estimate[["lat", "lon", "alt"]] = transform.perturb_lla(truth[["lat", "lon", "alt"]],
                                                                x[0:3])
        estimate[["VN", "VE", "VD"]] = rot.T @ truth[["VN", "VE", "VD"]].to_numpy() + x[3:6]
        estimate[["roll", "pitch", "heading"]] = transform.mat_to_rph(
            rot.T @ transform.mat_from_rph(truth[["roll", "pitch", "heading"]]))
        back = model.correct_pva(estimate[:9], x)  # pyins' feedback returns the truth
        assert np.allclose(back.to_numpy(), truth[:9].to_numpy(), atol=1e-8)
        c_nb = transform.mat_from_rph(truth[["roll", "pitch", "heading"]])
        v_antenna = (truth[["VN", "VE", "VD"]].to_numpy()
                     + c_nb @ np.cross(truth[["rate_x", "rate_y", "rate_z"]].to_numpy(), arm))
        gnss = pd.DataFrame([v_antenna], index=[0.0], columns=["VN", "VE", "VD"])
        meas = pyins.measurements.NedVelocity(gnss, 0.3, arm)
        z_est, h_used, _ = meas.compute_matrices(0.0, estimate, model)
        z_true, _, _ = meas.compute_matrices(0.0, truth, model)
        h_full = model.ned_velocity_error_jacobian(estimate, arm)
        dz = np.asarray(z_est - z_true, dtype=float)
        rows.append((np.abs(dz - h_used @ x).max(), np.abs(dz - h_full @ x).max(),
                     np.abs(dz).max()))
    rows = np.array(rows)
    print("innovation change |dz| (m/s), and |dz - H x| for the Jacobian pyins uses and for "
          "the one with the lever arm, over 5 random errors (phi ~ 1e-4 rad):")
    print(f"  |dz| up to {rows[:, 2].max():.2e}; pyins' H: residual up to {rows[:, 0].max():.2e}; "
          f"with the lever arm: {rows[:, 1].max():.2e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

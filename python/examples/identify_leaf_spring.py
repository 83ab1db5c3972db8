"""Identify the leaf spring's friction coefficient, yield stress and hardening modulus from a
noisy force-displacement curve.

A worked study that reads like a notebook: run it as a script
(``python python/examples/identify_leaf_spring.py [SCENE]``, default the paper's leaf spring)
or import ``identify``. The test suite runs it on ``leaf-spring-coarse``.

1. The "measurement": the block force over the whole load path (press, partial unload,
   reload) of the scene at its own (true) mu, sigma_y and H, plus Gaussian noise of 0.5 % of
   the largest force.
2. A start 20-30 % away from the truth.
3. ``scipy.optimize.least_squares`` on the residual (model - measured) / noise, once with the
   Jacobian from DDM (the value and the Jacobian from one analysis) and once with the
   optimiser's own two-point finite differences (one primal run per parameter per Jacobian).
4. What each took (iterations, analyses, wall time) and where it ended, against the truth and
   against the standard error the noise leaves in the estimate,
   sqrt(diag(s^2 (J^T J)^-1)).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from scipy.optimize import least_squares

import fricsens

PARAMS = ["mu", "sigma_y", "H"]
RESPONSE = "block-force"


def measurement(scene: fricsens.Scene, noise: float, seed: int):
    """The true curve and its noisy measurement; the noise's standard deviation."""
    truth = fricsens.Map(scene, PARAMS, [RESPONSE], method=None)
    b_true = np.array([scene.get(p) for p in PARAMS])
    clean = truth.fun(b_true)
    sd = noise * np.abs(clean).max()
    rng = np.random.default_rng(seed)
    return b_true, clean + rng.normal(0.0, sd, clean.shape), sd


def identify(scene_name: str = "leaf-spring", jacobian: str = "ddm", noise: float = 0.005,
             seed: int = 1, start=(0.7, 1.25, 0.75)):
    """Fit mu, sigma_y and H of ``scene_name`` to its own noisy curve; ``jacobian``: ``ddm``
    or ``fd`` (scipy's 2-point differences). Returns a dict of what happened."""
    scene = fricsens.Scene.load(scene_name)
    b_true, measured, sd = measurement(scene, noise, seed)
    x0 = b_true * np.asarray(start)
    m = fricsens.Map(scene, PARAMS, [RESPONSE], method="ddm" if jacobian == "ddm" else None)

    def residual(x):
        return (m.fun(x) - measured) / sd

    def residual_jac(x):
        return m.jac(x) / sd

    t = time.perf_counter()
    fit = least_squares(
        residual,
        x0,
        jac=residual_jac if jacobian == "ddm" else "2-point",
        x_scale=np.abs(x0),
        bounds=(np.zeros(3), np.full(3, np.inf)),
        xtol=1e-10,
        ftol=1e-10,
        gtol=1e-10,
    )
    seconds = time.perf_counter() - t
    # the estimate's standard error from the Jacobian at the optimum (residuals are in units of
    # the noise's standard deviation, so s^2 is the reduced chi-square)
    j = fit.jac
    dof = max(len(measured) - len(PARAMS), 1)
    s2 = 2.0 * fit.cost / dof
    cov = s2 * np.linalg.inv(j.T @ j)
    return {
        "jacobian": jacobian,
        "truth": b_true,
        "start": x0,
        "found": fit.x,
        "standard_error": np.sqrt(np.diag(cov)),
        "iterations": fit.nfev,
        "jacobians": fit.njev,
        "analyses": m.analyses,
        "seconds": seconds,
        "reduced_chi2": s2,
        "success": fit.success,
        "message": fit.message,
    }


def report(results):
    print(f"{'':14}" + "".join(f"{p:>24}" for p in PARAMS))
    r0 = results[0]
    print(f"{'truth':14}" + "".join(f"{v:24.6g}" for v in r0["truth"]))
    print(f"{'start':14}" + "".join(f"{v:24.6g}" for v in r0["start"]))
    for r in results:
        cells = "".join(
            f"{v:13.6g} +- {e:8.2g}" for v, e in zip(r["found"], r["standard_error"])
        )
        print(f"{r['jacobian'] + ' Jacobian':14}" + cells)
    print()
    for r in results:
        off = np.abs(r["found"] - r["truth"]) / r["standard_error"]
        print(
            f"{r['jacobian']:>4}: {r['iterations']} residual evaluations, {r['jacobians']} "
            f"Jacobians, {r['analyses']} analyses, {r['seconds']:.1f} s; reduced chi2 "
            f"{r['reduced_chi2']:.2f}; |found - truth| = {np.array2string(off, precision=2)} "
            f"standard errors; {r['message']}"
        )


if __name__ == "__main__":
    name = sys.argv[1] if len(sys.argv) > 1 else "leaf-spring"
    report([identify(name, "ddm"), identify(name, "fd")])

"""Record the v0.1 (single-elbow code, commit d52e451) trajectories used by test_chain_regression.

Run once on that commit; kept to show how the frozen file was made.
"""
import numpy as np, torquesim as ts, subprocess
from torquesim.solvers.coupling import IMEX
m = ts.default_model()
runs = {
 "monolithic_0.1ms": dict(method="monolithic", step=1e-4),
 "monolithic_0.25ms": dict(method="monolithic", step=2.5e-4),
 "partitioned_0.1ms": dict(method="partitioned", step=1e-4),
 "partitioned_body-first_0.1ms": dict(method="partitioned", step=1e-4, coupling=ts.Coupling(order="body-first")),
 "partitioned_muscles-first_0.1ms": dict(method="partitioned", step=1e-4, coupling=ts.Coupling(order="muscles-first")),
 "partitioned_linear_0.1ms": dict(method="partitioned", step=1e-4, coupling=ts.Coupling(predictor="linear")),
 "partitioned_m4_0.1ms": dict(method="partitioned", step=1e-4, coupling=ts.Coupling(muscle_substeps=4)),
 "partitioned_iter3_0.1ms": dict(method="partitioned", step=1e-4, coupling=ts.Coupling(iterations=3, tolerance=1e-12)),
 "partitioned_every-stage_0.1ms": dict(method="partitioned", step=1e-4, coupling=ts.Coupling(order="every-stage")),
 "imex_1ms": dict(method="imex", step=1e-3),
 "imex_5ms": dict(method="imex", step=5e-3),
 "partitioned_sdirk2_m2_1ms": dict(method="partitioned", step=1e-3, coupling=ts.Coupling(muscle_solver="sdirk2", muscle_substeps=2)),
 "reference": dict(method="reference"),
 "scipy_DOP853_1e-8": dict(method="scipy:DOP853", rtol=1e-8, atol=1e-11),
}
out = {}
for name, kw in runs.items():
    r = ts.simulate(m, check=False, **kw)
    k = max(1, int(round(1e-2 / (r.time[1]-r.time[0]))))
    out[name + "/states"] = r.states[::k]
    out[name + "/time"] = r.time[::k]
    out[name + "/cost"] = np.array([r.cost.steps, r.cost.rhs_body, r.cost.rhs_muscle])
    out[name + "/ratio"] = np.array([r.stability.max_step_ratio if r.stability else np.nan])
    print(name, r.states.shape, r.cost, r.stability.max_step_ratio if r.stability else None)
commit = subprocess.check_output(["git", "rev-parse", "HEAD"], text=True).strip()
out["commit"] = np.array(commit)
np.savez_compressed("tests/data/elbow_v0_1_trajectories.npz", **out)

import sys, glob, os, time, numpy as np
from sparselt.recovery.poisson import screened_poisson, screened_poisson_l1
from sparselt.analysis.metrics import trimmed_relative_mean_squared_error as trm
settings = eval(sys.argv[1])
for f in sorted(glob.glob("/work/runs/l1stop/*.npz")):
    d = np.load(f); name = os.path.basename(f)[:-4]; alpha = float(d["alpha"]); ref = d["reference"]; em = d["emission"]
    args = (d["primal"], d["gx"], d["gy"])
    l2 = trm(screened_poisson(*args, alpha=alpha).estimate + em, ref)[0]
    line = [f"{name:20s}"]
    for label, kw in settings:
        screened_poisson_l1(*args, alpha=alpha, **kw)
        t = time.perf_counter(); r = screened_poisson_l1(*args, alpha=alpha, **kw); t = time.perf_counter() - t
        line.append(f"{label}: {trm(r.estimate + em, ref)[0] / l2:.3f} it {r.iterations:3d} {t*1e3:4.0f}ms lum {np.mean(r.estimate+em)/np.mean(ref):.3f}")
    print(" | ".join(line), flush=True)

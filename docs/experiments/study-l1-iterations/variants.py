import sys, numpy as np, glob, os
from scipy.fft import dctn, idctn
from sparselt.recovery.poisson import screened_poisson, _laplacian_eigenvalues, forward_differences, difference_adjoint, l1_objective
from sparselt.analysis.metrics import trimmed_relative_mean_squared_error as trm

def solve(primal, gx, gy, alpha, penalty=1.0, iters=100, relax=1.6, balance=None, checks=(10,20,30,50,100)):
    h, w = primal.shape[:2]
    eig = _laplacian_eigenvalues(h, w, primal.shape[2:])
    b = (alpha * primal, gx, gy)
    rho = penalty * sum(p.size for p in b) / sum(np.abs(p).sum() for p in b)
    H = lambda I: (alpha * I,) + forward_differences(I)
    HT = lambda v: alpha * v[0] + difference_adjoint(v[1], v[2])
    I = screened_poisson(primal, gx, gy, alpha=alpha).estimate
    r = [hh - bb for hh, bb in zip(H(I), b)]
    z = [np.sign(x) * np.maximum(np.abs(x) - 1 / rho, 0) for x in r]
    u = [x - zz for x, zz in zip(r, z)]
    out = {}
    for k in range(1, iters + 1):
        rhs = HT([bb + zz - uu for bb, zz, uu in zip(b, z, u)])
        I = idctn(dctn(rhs, type=2, norm="ortho", axes=(0, 1)) / (alpha * alpha + eig), type=2, norm="ortho", axes=(0, 1))
        HI = H(I)
        zold = z
        hr = [relax * hi + (1 - relax) * (zz + bb) for hi, zz, bb in zip(HI, z, b)]
        v = [x - bb + uu for x, bb, uu in zip(hr, b, u)]
        z = [np.sign(x) * np.maximum(np.abs(x) - 1 / rho, 0) for x in v]
        u = [x - zz for x, zz in zip(v, z)]
        if balance and k % balance[2] == 0:
            pr = np.sqrt(sum(np.sum((hi - zz - bb) ** 2) for hi, zz, bb in zip(HI, z, b)))
            du = rho * np.sqrt(np.sum(HT([zz - zo for zz, zo in zip(z, zold)]) ** 2))
            mu, tau = balance[0], balance[1]
            if pr > mu * du:
                rho *= tau; u = [x / tau for x in u]
            elif du > mu * pr:
                rho /= tau; u = [x * tau for x in u]
        if k in checks:
            out[k] = I.copy()
    return out

files = sorted(glob.glob("/work/runs/l1stop/*.npz"))
configs = eval(sys.argv[1])
for f in files:
    d = np.load(f); name = os.path.basename(f)[:-4]
    ref = d["reference"]; em = d["emission"]; alpha = float(d["alpha"])
    l2 = trm(screened_poisson(d["primal"], d["gx"], d["gy"], alpha=alpha).estimate + em, ref)[0]
    line = [f"{name:22s} L2 {l2:.3g}"]
    for label, kw in configs:
        res = solve(d["primal"], d["gx"], d["gy"], alpha, **kw)
        line.append(label + " " + " ".join(f"{trm(res[k] + em, ref)[0]/l2:.3f}" for k in sorted(res)))
    print(" | ".join(line), flush=True)

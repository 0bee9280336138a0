"""Held-out check of the L1 solve against the L2 one at the same alpha (study for gradient-l1's l1_check)."""
import glob, json, sys, time
import numpy as np
from sparselt.experiments.standard_suite import standard_suite
from sparselt.experiments.suite_config import validate_suite
from sparselt.methods.gradient_domain import _merged, _estimates, gradient_estimates
from sparselt.recovery.poisson import held_out_alpha, screened_poisson_l1, screened_poisson, _block_standard_error
from sparselt.analysis.metrics import trimmed_relative_mean_squared_error


def reference_of(name):
    for path in glob.glob("/work/runs/suite41/out/references/*/reference.json"):
        info = json.load(open(path))
        if info["key"]["scene"]["name"] == name and info.get("complete"):
            return np.load(path.replace("reference.json", "image.npy"))
    return None


scenes = sys.argv[1].split(",")
out = open(sys.argv[2], "a")
for name in scenes:
    config = standard_suite("default", methods=["gradient-l1"], scenes=[name])
    member = config.scenes[0]
    setup = validate_suite(config)[member.name]
    loaded = setup.load(tuple(config.resolution))
    scene = loaded.scene
    reference = reference_of(name)
    for spp in (16, 64):
        for seed in (0, 1, 2):
            drawn = list(scene.sample_gradients(loaded.layout, tuple(setup.grid_shape), spp, 1000 + seed, offsets=4,
                                                shift="replay", halves=True))
            samples = _merged(drawn)
            separate = loaded.layout.count_camera_emission
            primal, gx, gy = _estimates(samples, spp, separate, None)
            halves = [_estimates(p, s, separate, None) for p, s in zip(drawn, (spp // 2, spp - spp // 2))]
            alpha, _ = held_out_alpha(halves)
            row = {"scene": name, "spp": spp, "seed": seed, "alpha": alpha}
            if np.isfinite(alpha):
                l2 = [screened_poisson(*h, alpha=alpha).estimate for h in halves]
                scale = 0.5 * (l2[0] + l2[1])
                weights = 1.0 / (np.mean(np.square(scale), axis=-1, keepdims=True) + 1e-2)
                judges = [halves[1][0], halves[0][0]]
                for k in (5, 12, 50):
                    start = time.perf_counter()
                    l1a = screened_poisson_l1(*halves[0], alpha=alpha, max_iterations=k).estimate
                    row[f"seconds_{k}"] = time.perf_counter() - start
                    l1b = screened_poisson_l1(*halves[1], alpha=alpha, max_iterations=k).estimate
                    terms = [weights * (np.square(l1 - j) - np.square(l2h - j)) for l1, l2h, j in zip((l1a, l1b), l2, judges)]
                    row[f"d_a_{k}"] = float(terms[0].sum())
                    row[f"se_a_{k}"] = float(_block_standard_error(terms[0]))
                    row[f"d_ab_{k}"] = float((terms[0] + terms[1]).sum())
                    row[f"se_ab_{k}"] = float(_block_standard_error(terms[0] + terms[1]))
                    row[f"l2score_{k}"] = float(sum((weights * np.square(l2h - j)).sum() for l2h, j in zip(l2, judges)))
                if reference is not None:
                    emission = gradient_estimates(samples.camera_emission, spp)[0] if separate else 0.0
                    full_l2 = screened_poisson(primal, gx, gy, alpha=alpha).estimate + emission
                    full_l1 = screened_poisson_l1(primal, gx, gy, alpha=alpha).estimate + emission
                    row["true_l1_over_l2"] = trimmed_relative_mean_squared_error(full_l1, reference)[0] / \
                        trimmed_relative_mean_squared_error(full_l2, reference)[0]
            out.write(json.dumps(row, default=float) + "\n"); out.flush()
            print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()}), flush=True)

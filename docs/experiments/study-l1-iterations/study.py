"""L1 solve: quality against iterations, and the primal's noise estimated from the halves (study for a stop rule)."""
import json, sys, time
import numpy as np
from sparselt.experiments.standard_suite import standard_suite
from sparselt.experiments.suite_config import validate_suite
from sparselt.methods import ComparisonContext
from sparselt.methods.gradient_domain import _merged, _estimates
from sparselt.recovery.poisson import held_out_alpha, screened_poisson_l1, screened_poisson
from sparselt.rendering.baseline import cached_reference
from sparselt.analysis.metrics import trimmed_relative_mean_squared_error

REFS = {'cornell-box': 35392, 'dof-sculptures': 4672, 'courtyard': 10368, 'sunlit-room': 8896, 'checker-dof': 6272,
        'glossy-interior': 21440, 'soft-shadows': 39744, 'thin-geometry': 4672, 'mirror-room': 8704,
        'outdoor-texture': 7040, 'glass-caustic': 29376}
CHECK = (0, 3, 5, 8, 12, 16, 20, 25, 30, 40, 50, 100, 200)
scenes = sys.argv[1].split(",")
out = open(sys.argv[2], "a")
for name in scenes:
    config = standard_suite("default", methods=["gradient-l1"], scenes=[name])
    member = config.scenes[0]
    setup = validate_suite(config)[member.name]
    loaded = setup.load(tuple(config.resolution))
    scene = loaded.scene
    reference, _ = cached_reference(scene, setup.kind, spp=REFS[name], max_depth=setup.max_depth, seed=0, progress=False,
                                    cache_directory="/work/runs/suite37/out/references")
    for spp in (16, 64):
        for seed in (0, 1):
            drawn = list(scene.sample_gradients(loaded.layout, tuple(setup.grid_shape), spp, 1000 + seed, offsets=4,
                                                shift="replay", halves=True))
            samples = _merged(drawn)
            separate = loaded.layout.count_camera_emission
            primal, gx, gy = _estimates(samples, spp, separate, None)
            halves = [_estimates(p, s, separate, None) for p, s in zip(drawn, (spp // 2, spp - spp // 2))]
            alpha, _ = held_out_alpha(halves)
            emission = 0.0
            if separate:
                from sparselt.methods.gradient_domain import gradient_estimates
                emission = gradient_estimates(samples.camera_emission, spp)[0]
            noise = float(np.sqrt(np.sum(np.square(halves[0][0] - halves[1][0])) / 4.0) / np.sqrt(np.sum(np.square(primal))))
            row = {"scene": name, "spp": spp, "seed": seed, "alpha": alpha, "noise": noise, "curve": {}}
            if np.isfinite(alpha):
                full = screened_poisson_l1(primal, gx, gy, alpha=alpha, max_iterations=200, tolerance=1e-12)
                row["history"] = list(full.residual_history)
                for k in CHECK:
                    if k == 0:
                        image = screened_poisson(primal, gx, gy, alpha=alpha).estimate
                    else:
                        image = screened_poisson_l1(primal, gx, gy, alpha=alpha, max_iterations=k, tolerance=1e-12).estimate
                    image = image + emission
                    row["curve"][k] = [trimmed_relative_mean_squared_error(image, reference)[0], float(np.mean(image) / np.mean(reference))]
            out.write(json.dumps(row, default=float) + "\n"); out.flush()
            print(name, spp, seed, alpha, round(noise, 4), {k: round(v[0], 6) for k, v in row["curve"].items()}, flush=True)

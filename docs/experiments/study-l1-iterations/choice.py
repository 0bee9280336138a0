"""Why does shift=auto pick reconnection on dof-sculptures? Pilot scores (untrimmed / trimmed) against the truth."""
import sys, numpy as np
from sparselt.experiments.standard_suite import standard_suite
from sparselt.experiments.suite_config import validate_suite
from sparselt.methods.gradient_domain import _merged, _estimates, gradient_estimates
from sparselt.recovery.poisson import held_out_choice, screened_poisson, screened_poisson_family, HELD_OUT_ALPHAS, DEFAULT_ALPHA
from sparselt.rendering.baseline import cached_reference
from sparselt.analysis.metrics import trimmed_relative_mean_squared_error as trm, relative_mean_squared_error as rm
REFS = {'cornell-box': 35392, 'dof-sculptures': 4672, 'courtyard': 10368}
name = sys.argv[1]
config = standard_suite("default", methods=["gradient-l1"], scenes=[name])
setup = validate_suite(config)[config.scenes[0].name]
loaded = setup.load(tuple(config.resolution)); scene = loaded.scene
ref, _ = cached_reference(scene, setup.kind, spp=REFS[name], max_depth=setup.max_depth, seed=config.reference_seed if hasattr(config,'reference_seed') else 0, progress=False, cache_directory="/work/runs/suite38a/out/references")
sep = loaded.layout.count_camera_emission
def est(parts, spps):
    return [_estimates(p, s, sep, None) for p, s in zip(parts, spps)]
for seed in range(3):
    pil = {}
    full = {}
    for i, sh in enumerate(("replay", "reconnection")):
        parts = list(scene.sample_gradients(loaded.layout, tuple(setup.grid_shape), 4, seed + i * (1 << 32), offsets=4, shift=sh, halves=True))
        pil[sh] = est(parts, (2, 2))
        s16 = scene.sample_gradients(loaded.layout, tuple(setup.grid_shape), 16, seed + 7 + i * (1 << 32), offsets=4, shift=sh)
        p, gx, gy = _estimates(s16, 16, sep, None)
        em = gradient_estimates(s16.camera_emission, 16)[0] if sep else 0
        full[sh] = {a: (screened_poisson(p, gx, gy, alpha=a).estimate if np.isfinite(a) else p) + em for a in HELD_OUT_ALPHAS}
    (ch, al), scores = held_out_choice(pil)
    (ch0, al0), _ = held_out_choice(pil, significance=0)
    print("significance 2:", ch, al, " least score:", ch0, al0)
    # trimmed score: per-pixel terms, top 0.1% dropped, per candidate
    labels = list(pil)
    truth = {(sh, a): (trm(full[sh][a], ref)[0], rm(full[sh][a], ref)) for sh in labels for a in HELD_OUT_ALPHAS}
    bestscore = {sh: min(v for (l, a), v in scores.items() if l == sh) for sh in labels}
    besttrue = {sh: min(truth[(sh, a)][0] for a in HELD_OUT_ALPHAS) for sh in labels}
    besttrueu = {sh: min(truth[(sh, a)][1] for a in HELD_OUT_ALPHAS) for sh in labels}
    print(name, seed, "chosen", ch, al, "score recon/replay %.3f" % (bestscore['reconnection'] / bestscore['replay']),
          "true trimmed recon/replay %.3f" % (besttrue['reconnection'] / besttrue['replay']),
          "true untrimmed %.3f" % (besttrueu['reconnection'] / besttrueu['replay']),
          "true at chosen alpha trimmed %.3f" % (truth[('reconnection', al)][0] / truth[('replay', al)][0]), flush=True)

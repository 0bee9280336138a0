"""The renderer: the only package of sparselt that imports Mitsuba 3 and Dr.Jit.

It turns a :class:`~sparselt.rendering.scenes.SceneSpec` into Mitsuba objects,
evaluates the path contribution ``f(S(u))`` for explicit primary-sample-space
vectors ``u`` laid out by a :class:`~sparselt.rendering.layout.PathLayout`
(thesis 2.1.6, 3.2), and renders baseline images with Mitsuba's own ``path``
integrator.

Modules
-------
runtime
    Starting Mitsuba and Dr.Jit (variants, LLVM discovery, threads, versions);
    imports neither until :func:`initialize` runs.
scene_dictionaries
    Transforms, scene and sensor dictionaries, cameras read back from
    sensors, coherent camera rays, scene files.
lanes
    Random lanes (TEA -> PCG32 per lane), explicit lanes, PSS vectors.
integrand
    The path contribution and its per-sample auxiliary outputs.
launch
    The one seam every estimator and integrator goes through: the seed
    folded to 32 bits (:func:`fold_seed`), the samples counted
    (:func:`count_samples`).
cells, pixels, pixel_statistics, gradients, guided
    One module per estimator.
integrators
    Mitsuba's own ``path`` and ``aov`` integrators.
scene
    :class:`MitsubaScene`: loading, autofocus, the camera's geometry; its
    estimator methods call the modules above.

Importing this package imports neither Mitsuba nor Dr.Jit.
"""

from .cells import sample_cells
from .gradients import (
                      GRADIENT_SHIFTS,
                      GradientSamples,
                      gradient_paths,
                      sample_gradients,
)
from .guided import GUIDED_STREAM, render_estimator, render_guided, warp_points
from .integrand import AUXILIARY_QUANTITIES, path_contribution
from .integrators import render_aovs, render_path
from .launch import SEED_LIMIT, SampleCount, count_samples, fold_seed, launch
from .pixel_statistics import PIXEL_STATISTICS, REDUCTIONS, sample_pixel_statistics
from .pixels import sample_pixels
from .runtime import (
                      DEFAULT_VARIANT,
                      MINIMUM_LLVM,
                      SUPPORTED_VARIANTS,
                      find_llvm_library,
                      initialize,
                      modules,
                      set_thread_count,
                      thread_count,
                      versions,
)
from .scene import MitsubaScene
from .scene_dictionaries import (
                      COHERENT_LENS_ANGLE,
                      camera_from_sensor,
                      coherent_camera_rays,
                      load_scene_file,
                      sensor_dictionary,
                      sensor_type,
                      to_mitsuba_dict,
                      to_mitsuba_transform,
)

__all__ = [
                      "AUXILIARY_QUANTITIES",
                      "COHERENT_LENS_ANGLE",
                      "DEFAULT_VARIANT",
                      "GRADIENT_SHIFTS",
                      "GUIDED_STREAM",
                      "MINIMUM_LLVM",
                      "PIXEL_STATISTICS",
                      "REDUCTIONS",
                      "SEED_LIMIT",
                      "SUPPORTED_VARIANTS",
                      "GradientSamples",
                      "MitsubaScene",
                      "SampleCount",
                      "camera_from_sensor",
                      "coherent_camera_rays",
                      "count_samples",
                      "find_llvm_library",
                      "fold_seed",
                      "gradient_paths",
                      "initialize",
                      "launch",
                      "load_scene_file",
                      "modules",
                      "path_contribution",
                      "render_aovs",
                      "render_estimator",
                      "render_guided",
                      "render_path",
                      "sample_cells",
                      "sample_gradients",
                      "sample_pixel_statistics",
                      "sample_pixels",
                      "sensor_dictionary",
                      "sensor_type",
                      "set_thread_count",
                      "thread_count",
                      "to_mitsuba_dict",
                      "to_mitsuba_transform",
                      "versions",
                      "warp_points",
]

"""``sparselt render``: Mitsuba's own path integrator on a scene, as an experiment of the protocol.

The baseline of every equal-time comparison is PT; this command renders it
alone into a folder (``image.exr``, ``image.png``, ``render.json``).
"""

from __future__ import annotations

from ..checks import check_integer
from ..provenance import environment_record
from ..rendering.baseline import check_finite_image, check_wavefront
from ..rendering.setup import DEFAULT_MAX_DEPTH, DEFAULT_VARIANT, SceneSetup
from .protocol import Experiment, run_experiment


class RenderExperiment(Experiment):
    """One render of a :class:`~sparselt.rendering.setup.SceneSetup` with Mitsuba's ``path`` integrator.

    No cells: the render is the report (written atomically once it is done).
    """

    kind = "render"

    def __init__(self, setup, *, spp, seed=0, resolution=None):
        self.setup, self.spp, self.seed = setup, spp, seed
        self.resolution = tuple(resolution) if resolution is not None else None

    def validate(self):
        check_integer("spp", self.spp, 1)
        check_integer("seed", self.seed, 0, 2**32 - 1)
        self.setup.validate()
        self.resolution = tuple(self.resolution or self.setup.film_resolution)
        if len(self.resolution) != 2:
            raise ValueError(f"resolution takes width,height, got {self.resolution}")
        for size in self.resolution:
            check_integer("resolution", size, 1)
        check_wavefront(self.resolution, self.spp)

    def identity(self):
        return {"spp": self.spp, "max_depth": self.setup.max_depth, "seed": self.seed,
                "resolution": list(self.resolution), "variant": self.setup.variant}

    def scene_identity(self):
        return self.setup.scene_identity

    def prepare(self):
        """Load the scene and render (nothing is written until the image is finite)."""
        loaded = self.setup.load(self.resolution).scene
        image, seconds = loaded.render_path(self.spp, self.setup.max_depth, self.seed)
        check_finite_image(image, self.setup.spec.name)
        width, height = self.resolution
        record = {
            "scene": self.setup.spec.name,
            "integrator": "path",
            "spp": self.spp,
            "max_depth": self.setup.max_depth,
            "seed": self.seed,
            "resolution": list(self.resolution),
            "aperture": loaded.camera.aperture_radius,
            "focus_distance": loaded.camera.focus_distance,
            "variant": self.setup.variant,
            "seconds": seconds,
            "samples_per_second": width * height * self.spp / seconds,
            "provenance": environment_record(),
        }
        return image, record

    def report(self, folder, state, records):
        image, record = state
        folder.write_exr("image.exr", image)
        folder.write_png("image.png", image)
        folder.write_json("render.json", record)
        return image, record


def render_reference(scene, out, *, spp, max_depth=DEFAULT_MAX_DEPTH, seed=0, resolution=None, aperture=None,
                     focus_distance=None, variant=DEFAULT_VARIANT, scene_spec=None, overwrite=False, parameters=()):
    """Render ``scene`` and write ``image.exr``, ``image.png`` and ``render.json`` into ``out``.

    Parameters
    ----------
    scene : str
        Built-in scene name or Mitsuba XML path.
    out : str
        Output folder (an :class:`~sparselt.storage.folder.ExperimentFolder`:
        the same render again rewrites it; another render there is refused
        unless ``overwrite``; foreign files are always refused). Nothing is
        written until the image is rendered, and then atomically.
    spp : int
        Samples per pixel (> 0).
    max_depth : int, optional
        Longest path, Mitsuba's convention (default 3).
    seed : int, optional
        Sampler seed.
    resolution : tuple of int, optional
        ``(width, height)``; default the scene's default resolution.
    aperture, focus_distance : float, optional
        Thin-lens override of the camera. An aperture alone focuses where the
        camera's central ray hits the scene; ``render.json`` records the
        focus distance used.
    parameters : sequence of (str, str), optional
        Values of the XML file's ``$name`` parameters (``-D name=value``).

    Returns
    -------
    image : ndarray, shape (height, width, 3)
    record : dict
        What ``render.json`` holds, including ``seconds`` (wall time of the
        render alone, after Dr.Jit synchronisation) and samples per second.
    """
    setup = SceneSetup(scene=scene if scene_spec is None else scene_spec.name, max_depth=max_depth,
                       parameters=parameters, aperture=aperture, focus_distance=focus_distance, variant=variant,
                       scene_spec=scene_spec)
    return run_experiment(RenderExperiment(setup, spp=spp, seed=seed, resolution=resolution), out,
                          overwrite=overwrite, progress=False)

"""Renderer adapter: the only module of sparselt that imports Mitsuba 3 and Dr.Jit.

It turns a :class:`~sparselt.rendering.scenes.SceneSpec` into Mitsuba objects,
evaluates the path contribution ``f(S(u))`` for explicit primary-sample-space
vectors ``u`` laid out by a :class:`~sparselt.rendering.layout.PathLayout`
(thesis 2.1.6, 3.2.2), and renders baseline images with Mitsuba's own ``path``
integrator.

Notes
-----
Dr.Jit's LLVM backend needs LLVM >= 17 (older versions fail with
"Cannot select: fminimum"). :func:`find_llvm_library` locates a suitable
``libLLVM`` before Dr.Jit is imported and exports ``DRJIT_LIBLLVM_PATH``.

Random numbers are a pure function of ``(seed, cell, sample index)``: each
lane seeds a PCG32 generator with a TEA hash of its cell and sample index, so
a signal is identical whatever the chunking. The seed and the first cell of a
chunk enter the kernel as opaque values, so one compiled kernel serves every
chunk and every seed.
"""

from __future__ import annotations

import dataclasses
import glob
import os
import re
import sys
import time

import numpy as np

from .. import kernels
from .scenes import Camera, Transform

DEFAULT_VARIANT = "llvm_ad_rgb"
SUPPORTED_VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb")
MINIMUM_LLVM = 17
ONE_MINUS_EPSILON = float(np.float32(1.0) - np.float32(2.0**-24))

_LLVM_HELP = (
    "Dr.Jit's LLVM backend needs libLLVM {minimum} or newer. On Debian 12 run "
    "'apt-get install -y libllvm19' (the Makefile's bootstrap does this), or "
    "'pip install karellen-llvm-core' and set DRJIT_LIBLLVM_PATH to its libLLVM.so."
)

mi = None
dr = None


def _llvm_version(path):
    match = re.search(r"libLLVM(?:-|\.so\.)(\d+)", os.path.basename(path))
    return int(match.group(1)) if match else None


def find_llvm_library():
    """Path of the newest libLLVM >= 17 on this machine, or ``None``.

    Looks in the system library folders, in ``/usr/lib/llvm-*/lib`` and in the
    running Python's prefix (where ``karellen-llvm-core`` installs).
    """
    patterns = [
        "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
        "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
        "/usr/lib/llvm-*/lib/libLLVM*.so*",
        "/usr/lib64/libLLVM*.so*",
        "/usr/local/lib/libLLVM*.so*",
        os.path.join(sys.prefix, "lib", "python*", "site-packages", "**", "libLLVM*.so*"),
    ]
    candidates = []
    for pattern in patterns:
        for path in glob.glob(pattern, recursive=True):
            version = _llvm_version(path)
            if version is not None and version >= MINIMUM_LLVM and os.path.isfile(path):
                candidates.append((version, path))
    return max(candidates)[1] if candidates else None


def initialize(variant=None):
    """Import Mitsuba with the requested variant and return the module.

    Parameters
    ----------
    variant : {'llvm_ad_rgb', 'cuda_ad_rgb'}, optional
        Default ``llvm_ad_rgb`` (CPU). ``cuda_ad_rgb`` needs an NVIDIA GPU.

    Raises
    ------
    ValueError
        Unsupported variant name.
    RuntimeError
        No usable LLVM (with the command that fixes it) or no CUDA device.
    """
    global mi, dr
    variant = variant or os.environ.get("SPARSELT_VARIANT", DEFAULT_VARIANT)
    if variant not in SUPPORTED_VARIANTS:
        raise ValueError(f"unsupported Mitsuba variant {variant!r}; choose one of {', '.join(SUPPORTED_VARIANTS)}")
    if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ and dr is None:
        library = find_llvm_library()
        if library is None:
            raise RuntimeError("no libLLVM >= %d found. " % MINIMUM_LLVM + _LLVM_HELP.format(minimum=MINIMUM_LLVM))
        os.environ["DRJIT_LIBLLVM_PATH"] = library
    try:
        import drjit as drjit_module
        import mitsuba as mitsuba_module

        mitsuba_module.set_variant(variant)
        probe = mitsuba_module.Float(1.0, 2.0) * 2.0
        drjit_module.eval(probe)
    except Exception as error:  # noqa: BLE001  (re-raised with the fix)
        if variant.startswith("cuda"):
            raise RuntimeError(f"Mitsuba variant {variant!r} is unavailable ({error}); is there an NVIDIA GPU?") from error
        raise RuntimeError(f"Mitsuba could not start its LLVM backend ({error}). " + _LLVM_HELP.format(minimum=MINIMUM_LLVM)) from error
    mi, dr = mitsuba_module, drjit_module
    return mi


def set_thread_count(count):
    """Size Dr.Jit's CPU thread pool (a Dask worker takes its share of the machine's cores)."""
    import drjit as drjit_module

    if drjit_module.thread_count() != int(count):
        drjit_module.set_thread_count(int(count))


def versions():
    """Versions of the rendering stack, for provenance records."""
    import drjit as drjit_module
    import mitsuba as mitsuba_module

    return {"mitsuba": mitsuba_module.__version__, "drjit": drjit_module.__version__}


# ---------------------------------------------------------------------------
# Scene conversion
# ---------------------------------------------------------------------------


def to_mitsuba_transform(transform):
    """Replay a :class:`Transform` chain with ``mi.ScalarTransform4f``."""
    result = mi.ScalarTransform4f()
    for operation in transform.operations:
        name, arguments = operation[0], operation[1:]
        if name == "translate":
            result = result.translate(list(arguments[0]))
        elif name == "rotate":
            result = result.rotate(list(arguments[0]), arguments[1])
        elif name == "scale":
            result = result.scale(list(arguments[0]))
        elif name == "look_at":
            result = result.look_at(origin=list(arguments[0]), target=list(arguments[1]), up=list(arguments[2]))
        elif name == "matrix":
            result = result @ mi.ScalarTransform4f([list(row) for row in arguments[0]])
        else:
            raise ValueError(f"unknown transform operation {name!r}")
    return result


def to_mitsuba_dict(value):
    """Recursively replace :class:`Transform` objects by Mitsuba transforms."""
    if isinstance(value, Transform):
        return to_mitsuba_transform(value)
    if isinstance(value, dict):
        return {key: to_mitsuba_dict(item) for key, item in value.items()}
    if isinstance(value, list):
        return [to_mitsuba_dict(item) for item in value]
    return value


def sensor_dictionary(camera, width, height):
    """Mitsuba sensor dictionary for ``camera`` with a box-filtered float film."""
    sensor = {
        "type": "thinlens" if camera.thin_lens else "perspective",
        "fov": camera.fov,
        "fov_axis": camera.fov_axis,
        "near_clip": camera.near_clip,
        "far_clip": camera.far_clip,
        "to_world": to_mitsuba_transform(camera.to_world),
        "sampler": {"type": "independent", "sample_count": 1},
        "film": {
            "type": "hdrfilm",
            "width": int(width),
            "height": int(height),
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
            "component_format": "float32",
        },
    }
    if camera.thin_lens:
        sensor["aperture_radius"] = camera.aperture_radius
        sensor["focus_distance"] = camera.focus_distance
    else:
        sensor["focus_distance"] = camera.focus_distance
    return sensor


# Mitsuba's class names of its sensor plugins -> the plugin type an XML file names.
_SENSOR_TYPES = {"PerspectiveCamera": "perspective", "ThinLensCamera": "thinlens", "IrradianceMeter": "irradiancemeter",
                 "RadianceMeter": "radiancemeter", "DistantSensor": "distant", "BatchSensor": "batch",
                 "OrthographicCamera": "orthographic"}


#: Widest lens (aperture radius over focus distance) whose camera rays are traced as coherent packets.
COHERENT_LENS_ANGLE = 0.025


def coherent_camera_rays(camera):
    """Whether camera rays are traced in Embree's coherent mode, as Mitsuba's own integrators trace them.

    Every sampler here runs a pixel's (or a cell's) lanes side by side, so
    neighbouring lanes' camera rays are neighbours, unless a wide lens
    spreads each pixel's bundle. Measured in issue 24 (PSS sampling against
    Mitsuba's ``path``, 64x64, depth 3): coherent mode makes the pinhole
    cornell-box 10-13% faster, the courtyard 5-8%, and both behind a lens of
    radius 0.05 at focus 4 (angle 0.0125) 5-10% faster, but dof-sculptures'
    lens (0.32 at 6.67, angle 0.048) 5-13% slower. The mode changes no hit
    on the procedural scenes; on the courtyard's meshes a few grazing rays
    in 10^4-10^5 hit another triangle of the same edge (Embree's packet and
    single-ray tests round differently), as in Mitsuba's own renders.
    """
    if not camera.thin_lens:
        return True
    return float(camera.aperture_radius) / float(camera.focus_distance) < COHERENT_LENS_ANGLE


def sensor_type(sensor):
    """The plugin type of a loaded Mitsuba sensor as an XML file names it (``'irradiancemeter'``), or its class name."""
    try:
        name = sensor.class_name()
    except Exception:  # noqa: BLE001  (older Mitsuba: the class name starts the description)
        name = str(sensor).split("[", 1)[0].strip()
    return _SENSOR_TYPES.get(name, name)


def camera_from_sensor(sensor):
    """Read a loaded Mitsuba perspective or thin-lens sensor back into a :class:`Camera`."""
    parameters = mi.traverse(sensor)
    matrix = np.array(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)
    keys = set(parameters.keys())

    def read(key, default):
        return float(np.ravel(np.asarray(parameters[key]))[0]) if key in keys else default

    fov = read("x_fov", None)
    if fov is None:
        kind = sensor_type(sensor)
        raise ValueError(f"the scene's sensor is of type {kind!r}, not a perspective or thin-lens camera; sparselt "
                         "samples the image plane and lens of those only: change the XML's <sensor type=...> to "
                         "'perspective' or 'thinlens'")
    aperture = read("aperture_radius", None)
    focus = read("focus_distance", 1000.0)
    near = read("near_clip", 0.001)
    far = read("far_clip", 1000.0)
    return Camera(
        to_world=Transform().matrix(matrix.tolist()),
        fov=fov,
        fov_axis="x",
        near_clip=near,
        far_clip=far,
        aperture_radius=aperture if aperture else None,
        focus_distance=focus,
    )


_UNDEFINED_PARAMETER = re.compile(r"undefined parameter: \$?([A-Za-z0-9_]+)")


def _load_scene_file(spec):
    """Load ``spec``'s XML file with its ``$name`` parameters, its referenced files checked first.

    Raises
    ------
    ValueError
        A referenced file is missing or not of its element's type
        (:func:`~sparselt.rendering.identity.check_xml_references`), or the
        file uses a parameter that has no value (the message shows ``-D``).
    """
    from .identity import check_xml_references

    check_xml_references(spec.filename, spec.parameters)
    mi.file_resolver().prepend(os.path.dirname(spec.filename))
    try:
        return mi.load_file(spec.filename, **dict(spec.parameters))
    except RuntimeError as error:
        match = _UNDEFINED_PARAMETER.search(str(error))
        if match is None:
            raise
        name = match.group(1)
        where = re.sub(r"^\[[^]]*\]\s*", "", str(error).strip())
        raise ValueError(f"scene {spec.name!r} uses parameter ${name} without a default; pass it as -D {name}=VALUE "
                         f"(Mitsuba: {where})") from None


class MitsubaScene:
    """A scene loaded into Mitsuba with a sensor at a given resolution.

    Parameters
    ----------
    spec : SceneSpec
        Built-in scene or scene file (see :func:`sparselt.rendering.scenes.get_scene`).
    resolution : tuple of int
        Film ``(width, height)``.
    variant : str, optional
        Mitsuba variant (default ``llvm_ad_rgb``).
    """

    def __init__(self, spec, resolution, *, variant=None):
        initialize(variant)
        self.spec = spec
        self.width, self.height = (int(v) for v in resolution)
        if spec.filename is not None:
            self.scene = _load_scene_file(spec)
            sensors = self.scene.sensors()
            if not sensors:
                raise ValueError(f"scene file {spec.filename!r} has no sensor to take the camera from")
            base_camera = camera_from_sensor(sensors[0])
        else:
            self.scene = mi.load_dict(to_mitsuba_dict(spec.objects))
            base_camera = spec.camera
        self.camera = spec.resolved_camera(base_camera)
        if spec.focuses_on_the_scene(base_camera):
            self.camera = self._focus_on_central_hit(self.camera)
        self.sensor = mi.load_dict(sensor_dictionary(self.camera, self.width, self.height))
        self._kernels = {}
        self.coherent_camera_rays = coherent_camera_rays(self.camera)

    def _focus_on_central_hit(self, camera):
        """``camera`` focused at the distance where the ray through the image centre hits the scene.

        A ray that hits nothing keeps the camera's focus distance, with a note
        on standard error.
        """
        pinhole = mi.load_dict(sensor_dictionary(dataclasses.replace(camera, aperture_radius=None), 1, 1))
        ray, _ = pinhole.sample_ray(time=0.0, sample1=0.5, sample2=mi.Point2f(0.5, 0.5), sample3=mi.Point2f(0.5, 0.5))
        interaction = self.scene.ray_intersect(ray)
        # Mitsuba's thin lens focuses on a plane at focus_distance along the camera's local z axis.
        hit = [float(np.ravel(np.asarray(coordinate))[0]) for coordinate in interaction.p]
        distance = float((to_mitsuba_transform(camera.to_world).inverse() @ mi.ScalarPoint3f(hit))[2])
        if not bool(np.ravel(np.asarray(interaction.is_valid()))[0]) or not (0 < distance < float("inf")):
            print(f"sparselt: note: the central ray of the camera of {self.spec.name!r} hits nothing; the thin lens "
                  f"focuses at the camera's own focus distance {camera.focus_distance:g} (give --focus-distance to "
                  "choose)", file=sys.stderr)
            return camera
        return camera.with_lens(focus_distance=distance)

    # -- primary-sample-space evaluation ------------------------------------

    def _path_contribution(self, layout, samples, auxiliary=None):
        """Radiance of the paths defined by explicit PSS samples.

        ``samples`` maps each name in ``layout.dimensions`` to a ``mi.Float``.
        The estimator follows Mitsuba's ``path`` integrator (MIS with the power
        heuristic between next-event estimation and BSDF sampling) without
        Russian roulette; ``layout`` says which vertices sample lights and which
        emission hits count (see :mod:`sparselt.rendering.layout`).

        ``auxiliary``, a dict, receives the per-sample quantities of
        :data:`AUXILIARY_QUANTITIES` computed in the same kernel (the
        frequency-analysis filters' inputs, Mehta et al. 2012-2014).
        """
        scene = self.scene
        context = mi.BSDFContext()
        position = mi.Point2f(samples["x"], samples["y"])
        aperture = mi.Point2f(samples["lens_u"], samples["lens_v"]) if layout.thin_lens else mi.Point2f(0.5, 0.5)
        ray, ray_weight = self.sensor.sample_ray(time=0.0, sample1=0.5, sample2=position, sample3=aperture)
        throughput = mi.Color3f(ray_weight)
        result = mi.Color3f(0.0)
        active = mi.Bool(True)

        interaction = scene.ray_intersect(ray, mi.RayFlags.All, self.coherent_camera_rays, active)
        if auxiliary is not None:
            self._record_primary(auxiliary, interaction, samples, layout)
        if layout.count_camera_emission:
            result += throughput * interaction.emitter(scene).eval(interaction, active)
            if auxiliary is not None:
                auxiliary["camera_emission"] = mi.Color3f(result)

        for index, plan in enumerate(layout.vertices, start=1):
            active &= interaction.is_valid()
            bsdf = interaction.bsdf(ray)

            if plan.next_event:
                light_sample = mi.Point2f(samples[f"light{index}_u"], samples[f"light{index}_v"])
                active_light = active & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
                direction_sample, emitter_weight = scene.sample_emitter_direction(interaction, light_sample, True, active_light)
                active_light &= direction_sample.pdf != 0.0
                local_direction = interaction.to_local(direction_sample.d)
                bsdf_value, bsdf_pdf = bsdf.eval_pdf(context, interaction, local_direction, active_light)
                weight = dr.select(direction_sample.delta, 1.0, _power_heuristic(direction_sample.pdf, bsdf_pdf))
                result += dr.select(active_light, throughput * weight * bsdf_value * emitter_weight, 0.0)

            direction = mi.Point2f(samples[f"bsdf{index}_u"], samples[f"bsdf{index}_v"])
            bsdf_sample, bsdf_weight = bsdf.sample(context, interaction, samples[f"lobe{index}"], direction, active)
            throughput = dr.select(active, throughput * bsdf_weight, 0.0)
            active &= dr.max(throughput) > 0.0
            ray = interaction.spawn_ray(interaction.to_world(bsdf_sample.wo))
            next_interaction = scene.ray_intersect(ray, active)
            if auxiliary is not None and index == 1:
                hit = active & next_interaction.is_valid()
                auxiliary["secondary_distance"] = dr.select(hit, next_interaction.t, dr.inf)
                auxiliary["secondary_diffuse"] = mi.has_flag(bsdf_sample.sampled_type, mi.BSDFFlags.Diffuse)

            if plan.count_emission_hit:
                emitter_sample = mi.DirectionSample3f(scene, si=next_interaction, ref=interaction)
                emission = emitter_sample.emitter.eval(next_interaction, active)
                if plan.next_event:
                    delta = mi.has_flag(bsdf_sample.sampled_type, mi.BSDFFlags.Delta)
                    light_pdf = scene.pdf_emitter_direction(interaction, emitter_sample, active & ~delta)
                    emission *= _power_heuristic(bsdf_sample.pdf, light_pdf)
                result += dr.select(active, throughput * emission, 0.0)
            interaction = next_interaction
        return result

    def _record_primary(self, auxiliary, interaction, samples, layout):
        """The camera ray's hit: camera-space depth, shading normal, diffuse reflectance; the lens sample."""
        origin, forward = self._camera_axis()
        valid = interaction.is_valid()
        offset = interaction.p - mi.Point3f(*origin)
        depth = offset.x * forward[0] + offset.y * forward[1] + offset.z * forward[2]
        auxiliary["primary_depth"] = dr.select(valid, depth, dr.inf)
        auxiliary["primary_normal"] = dr.select(valid, interaction.sh_frame.n, 0.0)
        bsdf = interaction.bsdf()
        auxiliary["diffuse_albedo"] = dr.select(valid, mi.Color3f(bsdf.eval_diffuse_reflectance(interaction, valid)),
                                                0.0)
        if layout.thin_lens:
            auxiliary["lens_u"] = samples["lens_u"]
            auxiliary["lens_v"] = samples["lens_v"]
        auxiliary["camera_emission"] = mi.Color3f(dr.zeros(mi.Float, dr.width(depth)))
        # Defaults for quantities a path without a first bounce never sets.
        auxiliary["secondary_distance"] = dr.full(mi.Float, dr.inf, dr.width(depth))
        auxiliary["secondary_diffuse"] = dr.full(mi.Bool, False, dr.width(depth))

    def _camera_axis(self):
        """World-space position of the camera and its unit optical axis (local +z)."""
        matrix = np.array(self.sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)
        forward = matrix[:3, 2] / np.linalg.norm(matrix[:3, 2])
        return tuple(float(v) for v in matrix[:3, 3]), tuple(float(v) for v in forward)

    def lens_geometry(self):
        """The thin lens as the frequency analysis of depth of field needs it (Mehta et al. 2014, 3).

        Returns
        -------
        dict
            ``aperture_radius`` and ``focus_distance`` (scene units; aperture 0
            for a pinhole), ``pixels_per_tangent``: film pixels per unit of
            ``tan`` of the angle off the optical axis along x (``width / (2 tan(fov_x / 2))``).
        """
        camera = self.camera
        return {"aperture_radius": float(camera.aperture_radius or 0.0),
                "focus_distance": float(camera.focus_distance),
                "pixels_per_tangent": self._pixels_per_tangent()}

    def _pixels_per_tangent(self):
        parameters = mi.traverse(self.sensor)
        fov = float(np.ravel(np.asarray(parameters["x_fov"]))[0])
        return self.width / (2.0 * np.tan(np.radians(fov) / 2.0))

    def sample_cells(self, layout, grid_shape, first_cell, cell_count, spp, seed, *, cells=None):
        """Mean of ``spp`` jittered samples in each of a run of grid cells.

        Parameters
        ----------
        layout : PathLayout
            Meaning of every PSS dimension; ``layout.axes`` are gridded.
        grid_shape : tuple of int
            Resolution of each axis, in ``layout.axes`` order.
        first_cell, cell_count : int
            The cells ``first_cell .. first_cell + cell_count - 1`` in C order.
        spp : int
            Jittered samples per cell.
        seed : int
            Seed in ``[0, 2**32)``.

        cells : array_like of int, optional
            Sample these cells (flat C-order indices, any order, repeats
            allowed) instead of the run; ``first_cell`` and ``cell_count``
            are then ignored. A cell's samples are the same either way: the
            Sparse Fourier Transform's oracle reads single cells through it.

        Returns
        -------
        means : ndarray, shape (cell_count, 3), float32
            Per-cell mean RGB over the finite samples (non-finite ones count as 0).
        nonfinite : ndarray, shape (cell_count,), int64
            Number of samples in each cell whose value was NaN or infinite.
        """
        items = None
        if cells is not None:
            cells = np.ascontiguousarray(cells, dtype=np.uint32)
            cell_count, items = int(cells.size), mi.UInt32(cells)
        cell, generator, _ = _lanes(cell_count, spp, seed, first=first_cell, items=items)
        strides = np.cumprod((1,) + tuple(grid_shape[:0:-1]))[::-1]
        axis_of = {name: position for position, name in enumerate(layout.axes)}
        samples = {}
        for name in layout.dimensions:
            uniform = generator.next_float32()
            if name in axis_of:
                position = axis_of[name]
                resolution = int(grid_shape[position])
                coordinate = (cell // int(strides[position])) % resolution
                uniform = dr.minimum((mi.Float(coordinate) + uniform) * (1.0 / resolution), ONE_MINUS_EPSILON)
            samples[name] = uniform

        value, finite = _zero_nonfinite(self._path_contribution(layout, samples))
        invalid = dr.select(finite, mi.UInt32(0), mi.UInt32(1))
        # One kernel for all outputs: reducing unevaluated channels one by one
        # would trace and run the whole path kernel once per channel.
        dr.eval(value, invalid)
        scale = 1.0 / spp
        sums = [dr.block_sum(channel, spp) * scale for channel in (value.x, value.y, value.z)]
        bad = dr.block_sum(invalid, spp)
        dr.eval(sums, bad)
        return _rgb_array(sums), np.asarray(bad, dtype=np.int64)

    def sample_pixels(self, layout, grid_shape, spp, seed, first_pixel=0, pixel_count=None, resolution=None,
                      auxiliary=(), lanes=None):
        """``spp`` path samples per film pixel, each at a uniformly random point of the pixel's PSS box.

        The image-plane dimensions are jittered inside the film pixel; every
        other dimension (the signal's non-image axes included) is uniform on
        ``[0, 1)``, so the grid cell a sample falls in is uniformly random among
        the pixel's cells and the sample is jittered inside it (thesis 8.1.1).
        Random numbers come from the same TEA-seeded PCG32 streams as
        :meth:`sample_cells`, keyed by (seed, pixel, sample index).

        Parameters
        ----------
        layout : PathLayout
            Meaning of every PSS dimension; ``layout.axes`` are gridded.
        grid_shape : tuple of int
            Signal grid, in ``layout.axes`` order. Its image axes must divide
            the film resolution.
        spp : int
            Samples per pixel.
        seed : int
            Seed in ``[0, 2**32)``.
        first_pixel, pixel_count : int, optional
            Film pixels ``first_pixel ..`` in row-major order (row ``y``);
            default every pixel.
        resolution : tuple of int, optional
            ``(width, height)`` of the pixel grid the samples are drawn per
            (default the film's): a pilot pass draws per cell of a coarser map.
        auxiliary : tuple of str, optional
            Names of :data:`AUXILIARY_QUANTITIES` to return as well.
        lanes : tuple of two int arrays, optional
            ``(pixels, sample_indices)``: draw exactly these samples (any
            number per pixel: an adaptive allocation) instead of ``spp`` per
            pixel of the run; ``spp``, ``first_pixel`` and ``pixel_count``
            are then ignored. Sample ``i`` of pixel ``p`` is the same sample
            either way.

        Returns
        -------
        values : ndarray, shape (pixel_count * spp, 3), float32
            Path contributions, pixel-major (the ``spp`` samples of a pixel are
            consecutive); NaN or infinite ones are replaced by 0.
        cells : ndarray, shape (pixel_count * spp,), int64
            Flat C-order grid cell of each sample.
        nonfinite : int
            Number of samples that were NaN or infinite.
        auxiliary : dict, only when ``auxiliary`` names quantities
            Each requested name of :data:`AUXILIARY_QUANTITIES` -> a numpy
            array with one row per sample, computed in the same kernel.
        """
        unknown = sorted(set(auxiliary) - set(AUXILIARY_QUANTITIES))
        if unknown:
            raise ValueError(f"unknown auxiliary quantities {unknown}; choose from {', '.join(AUXILIARY_QUANTITIES)}")
        if any(name.startswith("lens_") for name in auxiliary) and not layout.thin_lens:
            raise ValueError("lens coordinates need a thin-lens camera (give --aperture)")
        film_width, film_height = (self.width, self.height) if resolution is None else (int(v) for v in resolution)
        pixel_count = film_width * film_height - int(first_pixel) if pixel_count is None else int(pixel_count)
        _, samples, cell = self._pixel_lanes(layout, grid_shape, spp, seed, first_pixel, pixel_count,
                                             (film_width, film_height), lanes)
        recorded = {} if auxiliary else None
        value, finite = _zero_nonfinite(self._path_contribution(layout, samples, recorded))
        extra = [recorded[name] for name in auxiliary]
        dr.eval(value, cell, finite, *extra)
        result = (_rgb_array((value.x, value.y, value.z)), np.asarray(cell, dtype=np.int64), _count_false(finite))
        if not auxiliary:
            return result
        return result + ({name: _to_numpy(recorded[name]) for name in auxiliary},)

    def _pixel_lanes(self, layout, grid_shape, spp, seed, first_pixel, pixel_count, film_size, lanes):
        """The PSS vectors of pixel samples (see :meth:`sample_pixels`): ``(pixel, samples, cell)`` per lane."""
        if lanes is None:
            pixel, generator, _ = _lanes(pixel_count, spp, seed, first=first_pixel)
        else:
            pixel, generator = _explicit_lanes(lanes[0], lanes[1], seed)
        width = dr.opaque(mi.UInt32, film_size[0])
        samples, cell = _pss_vector(layout, grid_shape, generator, pixel % width, pixel // width, film_size)
        return pixel, samples, cell

    def sample_pixel_statistics(self, layout, grid_shape, seed, names, *, spp=None, lanes=None):
        """Per-pixel reductions of per-sample quantities (:data:`PIXEL_STATISTICS`), reduced where they are drawn.

        The samples are exactly those of :meth:`sample_pixels` (the same
        random numbers): ``spp`` per film pixel, or the explicit ``lanes``
        ``(pixels, sample_indices)`` sorted by pixel. Nothing per sample leaves
        the kernel but the sums of an explicit-lanes pass, which are reduced in
        numpy (in a fixed order: the same seed gives the same bytes; the
        kernel's atomic additions would not).

        Parameters
        ----------
        layout : PathLayout
        grid_shape : tuple of int
        seed : int
        names : tuple of str
            Keys of :data:`PIXEL_STATISTICS`.
        spp : int, optional
            Samples per pixel of every film pixel (one of ``spp``, ``lanes``).
        lanes : tuple of two int arrays, optional

        Returns
        -------
        statistics : dict
            name -> float64 array ``(pixels,)`` or ``(pixels, 3)`` over every
            film pixel (pixels without samples hold the reduction's identity).
        nonfinite : int
            Samples that were NaN or infinite (counted as 0).
        """
        unknown = sorted(set(names) - set(PIXEL_STATISTICS))
        if unknown:
            raise ValueError(f"unknown pixel statistics {unknown}; choose from {', '.join(PIXEL_STATISTICS)}")
        if (spp is None) == (lanes is None):
            raise ValueError("give exactly one of spp and lanes")
        pixels = self.width * self.height
        _, samples, _ = self._pixel_lanes(layout, grid_shape, spp, seed, 0, pixels, (self.width, self.height), lanes)
        recorded = {}
        value, finite = _zero_nonfinite(self._path_contribution(layout, samples, recorded))
        quantities = {name: _statistic_quantity(name, value, recorded) for name in names}
        flat = {name: [quantity.x, quantity.y, quantity.z] if dr.size_v(quantity) == 3 else [quantity]
                for name, quantity in quantities.items()}
        dr.eval(finite, *[channel for channels in flat.values() for channel in channels])
        nonfinite = _count_false(finite)
        results = {}
        if lanes is None:
            operations = {"sum": dr.ReduceOp.Add, "min": dr.ReduceOp.Min, "max": dr.ReduceOp.Max}
            reduced = {name: [dr.block_reduce(operations[PIXEL_STATISTICS[name]], channel, int(spp))
                              for channel in channels] for name, channels in flat.items()}
            dr.eval(*[channel for channels in reduced.values() for channel in channels])
            for name, channels in reduced.items():
                results[name] = _stacked(channels)
            return results, nonfinite
        pixel_ids = np.ascontiguousarray(lanes[0], dtype=np.int64)
        starts = np.flatnonzero(np.concatenate(([True], pixel_ids[1:] != pixel_ids[:-1])))
        owners = pixel_ids[starts]
        for name, channels in flat.items():
            reduction = PIXEL_STATISTICS[name]
            per_lane = _stacked(channels)
            operation, identity = REDUCTIONS[reduction]
            result = np.full((pixels,) + per_lane.shape[1:], identity)
            if owners.size:
                result[owners] = operation.reduceat(per_lane, starts, axis=0)
            results[name] = result
        return results, nonfinite

    def sample_gradients(self, layout, grid_shape, spp, seed, *, offsets=4):
        """Gradient-domain path samples: every base sample replayed at the neighbouring pixels, in one kernel.

        Base sample ``i`` of pixel ``p`` is :meth:`sample_pixels`' sample ``i``
        of ``p`` (the same random numbers). Its offset paths replay those
        numbers with the film position moved by exactly one pixel, to each
        neighbour of :data:`GRADIENT_SHIFTS` ``[offsets]`` (the shift map of
        primary sample space: a translation, Jacobian 1; Kettunen et al. 2015,
        3 and 5.1 use the 4 neighbours). An offset landing outside the film is
        not traced (counted 0). The base and offset paths of a pass are one
        Dr.Jit launch (lane ``((pixel * (1 + offsets)) + shift) * n + sample``),
        reduced per pixel and shift inside it: nothing per sample leaves it.

        Parameters
        ----------
        layout : PathLayout
        grid_shape : tuple of int
            Signal grid (the cells are not used; the PSS vectors are those of
            :meth:`sample_pixels`).
        spp : int
            Base samples per pixel.
        seed : int
        offsets : {4, 2}
            Neighbours per base sample: ``+x, -x, +y, -y`` or ``+x, +y``.

        Returns
        -------
        sums : ndarray, shape (height, width, 1 + offsets, 3), float64
            Per base pixel: the sum over its ``spp`` base samples of the base
            path's contribution (index 0) and of each offset path's (index
            ``1 + k`` for shift ``k``); 0 for offsets outside the film.
        camera_emission : ndarray, shape (height, width, 1 + offsets, 3), float64
            The same sums of the part of each contribution that is emission
            seen directly by the camera ray (0 where the layout does not count
            it), reduced in the same launch.
        nonfinite : int
            Paths (base or offset, inside the film) whose value was NaN or
            infinite, counted as 0.
        """
        if offsets not in GRADIENT_SHIFTS:
            raise ValueError(f"offsets must be one of {sorted(GRADIENT_SHIFTS)}, got {offsets!r}")
        spp = int(spp)
        if spp < 1:
            raise ValueError(f"spp must be >= 1, got {spp}")
        shifts = ((0, 0),) + GRADIENT_SHIFTS[offsets]
        paths_per_base = len(shifts)
        width, height = self.width, self.height
        pixels = width * height
        per_launch = max(1, min(spp, GRADIENT_LANE_LIMIT // (pixels * paths_per_base)))
        shift_x = mi.Int32([dx for dx, _ in shifts])
        shift_y = mi.Int32([dy for _, dy in shifts])
        outside_per_sample = paths_per_base * pixels - gradient_paths(width, height, offsets)
        sums = np.zeros((pixels * paths_per_base, 3))
        emission_sums = np.zeros((pixels * paths_per_base, 3))
        nonfinite = 0
        for first in range(0, spp, per_launch):
            count = min(per_launch, spp - first)
            index = dr.arange(mi.UInt32, pixels * paths_per_base * count)
            samples_per_block = dr.opaque(mi.UInt32, count)
            block = index // samples_per_block
            shift = block % dr.opaque(mi.UInt32, paths_per_base)
            pixel = block // dr.opaque(mi.UInt32, paths_per_base)
            generator = _seeded_generator(pixel, index % samples_per_block + dr.opaque(mi.UInt32, first), seed, 0)
            film_width = dr.opaque(mi.Int32, width)
            target_x = mi.Int32(pixel % mi.UInt32(film_width)) + dr.gather(mi.Int32, shift_x, shift)
            target_y = mi.Int32(pixel // mi.UInt32(film_width)) + dr.gather(mi.Int32, shift_y, shift)
            inside = (target_x >= 0) & (target_x < film_width) & (target_y >= 0) & (target_y < dr.opaque(mi.Int32, height))
            samples, _ = _pss_vector(layout, grid_shape, generator, mi.UInt32(dr.select(inside, target_x, 0)),
                                     mi.UInt32(dr.select(inside, target_y, 0)), (width, height))
            recorded = {}
            value, finite = _zero_nonfinite(self._path_contribution(layout, samples, recorded), inside)
            # A layout that counts no emission seen directly leaves its sums 0 without reducing zeros.
            channels = [value.x, value.y, value.z]
            if layout.count_camera_emission:
                emission = dr.select(finite, recorded["camera_emission"], 0.0)
                channels += [emission.x, emission.y, emission.z]
            dr.eval(finite, *channels)
            nonfinite += _count_false(finite) - count * outside_per_sample
            reduced = [dr.block_sum(channel, count) for channel in channels]
            dr.eval(reduced)
            sums += _stacked(reduced[:3])
            if layout.count_camera_emission:
                emission_sums += _stacked(reduced[3:])
        shape = (height, width, paths_per_base, 3)
        return sums.reshape(shape), emission_sums.reshape(shape), nonfinite

    def render_estimator(self, layout, spp, seed):
        """Path tracing of the kind's own estimator (every PSS dimension uniform), ``spp`` per pixel, in one kernel.

        The same kernel as :meth:`render_guided` without a map: the fair
        path-tracing baseline for kinds Mitsuba's ``path`` cannot render alone
        (``indirect``). Returns ``(image, nonfinite)``.
        """
        return self.render_guided(layout, None, None, None, spp, seed, mode="per-pixel")

    def render_guided(self, layout, map_shape, tables, densities, spp, seed, *, mode):
        """Render the film with primary samples drawn from a piecewise-constant importance map (thesis 6.2.1, 8.3).

        The map's axes are ``layout.axes`` (the signal kind's axes) with
        resolution ``map_shape``; every other PSS dimension stays uniform. The
        guided vector is warped inside the kernel, one axis at a time, by a
        binary search in the conditional CDF of that axis given the cells
        already chosen (:meth:`ImportanceMap.level_tables`); the remainder of
        the uniform is the jitter inside the cell. Each sample contributes
        ``f(u) / p(u)``.

        Parameters
        ----------
        layout : PathLayout
        map_shape : tuple of int
            Map resolution per axis; its image axes divide the film resolution.
        tables : list of ndarray
            Conditional CDFs per axis (level ``k`` of shape ``map_shape[:k + 1]``).
        densities : ndarray, shape (prod(map_shape),)
            Density on the unit hypercube of each cell: of all axes
            (``mode='global'``) or of the non-image axes given the image cell
            (``mode='per-pixel'``).
        spp : int
            Samples per film pixel (``'global'``: on average).
        seed : int
        mode : {'global', 'per-pixel'}
            ``'global'``: every sample picks a cell over all axes, the image
            plane included, and is splatted into the film pixel it lands in.
            ``'per-pixel'``: each pixel gets ``spp`` samples, jittered on the
            image plane, and the other axes follow the map's conditional at the
            pixel's image cell.

        Returns
        -------
        image : ndarray, shape (height, width, 3), float32
        nonfinite : int
            Samples that were NaN or infinite (counted as 0).
        """
        pixels = self.width * self.height
        # Global mode: the lanes run grouped by the film pixel they land in (the same samples, in another
        # order), so that neighbouring lanes trace neighbouring rays and read the same rows of the map.
        order = self._global_order(layout, map_shape, tables, spp, seed) if mode == "global" else None
        pixel, generator, _ = _lanes(pixels, spp, seed, stream=GUIDED_STREAM, order=order)
        width = dr.opaque(mi.UInt32, self.width)
        first_axis = 0 if mode == "global" else 2
        uniforms = {name: generator.next_float32() for name in layout.dimensions}
        if mode == "per-pixel":
            uniforms["x"] = _in_pixel(pixel % width, uniforms["x"], self.width)
            uniforms["y"] = _in_pixel(pixel // width, uniforms["y"], self.height)
        if tables is None:  # no map: plain path tracing of the kind's estimator
            density = mi.Float(1.0)
        else:
            if mode == "per-pixel":
                cell_x = mi.UInt32(uniforms["x"] * dr.opaque(mi.Float, float(map_shape[0])))
                cell_y = mi.UInt32(uniforms["y"] * dr.opaque(mi.Float, float(map_shape[1])))
                prefix = dr.minimum(cell_x, map_shape[0] - 1) * map_shape[1] + dr.minimum(cell_y, map_shape[1] - 1)
            else:
                prefix = mi.UInt32(0)
            prefix = _warp_axes(map_shape, tables, uniforms, layout.axes, prefix, first_axis)
            density = dr.gather(mi.Float, mi.Float(np.ascontiguousarray(densities, dtype=np.float32)), prefix)

        value, finite = _zero_nonfinite(self._path_contribution(layout, uniforms) / density, density > 0)
        scale = 1.0 / int(spp)
        if mode == "per-pixel":
            dr.eval(value, finite)
            sums = [dr.block_sum(channel, int(spp)) * scale for channel in (value.x, value.y, value.z)]
        else:  # splatted in lane order, on the host: the same bytes for the same seed, whatever the threads did
            target = self._film_pixel(uniforms)
            weighted = [channel * scale for channel in (value.x, value.y, value.z)]
            dr.eval(weighted, target, finite)
            image = kernels.ordered_sums(np.asarray(target, dtype=np.uint32),
                                         [np.asarray(channel, dtype=np.float32) for channel in weighted], pixels)
            return image.reshape(self.height, self.width, 3), _count_false(finite)
        dr.eval(sums, finite)
        return _rgb_array(sums).reshape(self.height, self.width, 3), _count_false(finite)

    def _film_pixel(self, uniforms):
        """Flat film pixel (row-major) of each lane's image-plane coordinates ``uniforms['x'], uniforms['y']``."""
        target_x = dr.minimum(mi.UInt32(uniforms["x"] * self.width), self.width - 1)
        target_y = dr.minimum(mi.UInt32(uniforms["y"] * self.height), self.height - 1)
        return target_y * self.width + target_x

    def _global_order(self, layout, map_shape, tables, spp, seed):
        """The lanes of a global-mode render, grouped by the film pixel each lands in (stable within a pixel).

        A first, cheap kernel draws each lane's image-plane numbers and warps
        them through the map's first two levels exactly as the render does;
        a counting sort of the pixels gives the order. Returns a ``mi.UInt32``
        permutation of the lane numbers.
        """
        pixels = self.width * self.height
        _, generator, _ = _lanes(pixels, spp, seed, stream=GUIDED_STREAM)
        uniforms = {name: generator.next_float32() for name in layout.dimensions}  # unused draws are not computed
        if tables is not None:
            _warp_axes(map_shape[:2], tables[:2], uniforms, layout.axes, mi.UInt32(0), 0)
        target = self._film_pixel(uniforms)
        dr.eval(target)
        return mi.UInt32(kernels.counting_order(np.asarray(target, dtype=np.uint32), pixels))

    # -- baseline -------------------------------------------------------------

    def render_path(self, spp, max_depth, seed=0):
        """Render with Mitsuba's own ``path`` integrator.

        Returns
        -------
        image : ndarray, shape (height, width, 3), float32
        seconds : float
            Wall time of the render, synchronised with ``dr.sync_thread``.
        """
        integrator = mi.load_dict({"type": "path", "max_depth": int(max_depth), "rr_depth": 1 << 30,
                                   "hide_emitters": bool(self.spec.hide_emitters)})
        dr.sync_thread()
        start = time.perf_counter()
        image = mi.render(self.scene, sensor=self.sensor, integrator=integrator, spp=int(spp), seed=int(seed))
        array = np.array(image, dtype=np.float32)
        dr.sync_thread()
        return array, time.perf_counter() - start

    def render_aovs(self, spp, seed=0):
        """Albedo, shading normal and depth from Mitsuba's ``aov`` integrator (the denoisers' feature buffers).

        Same camera, film and box filter as :meth:`render_path`; ``spp``
        samples per pixel, so the buffers are anti-aliased and, for a thin
        lens, blurred by the aperture like the image.

        Returns
        -------
        buffers : dict
            ``albedo`` (height, width, 3), ``normal`` (height, width, 3, world
            space, not renormalised after averaging), ``depth`` (height, width):
            float32.
        seconds : float
            Wall time, synchronised with ``dr.sync_thread``.
        """
        integrator = mi.load_dict({"type": "aov", "aovs": "albedo:albedo,normal:sh_normal,depth:depth"})
        dr.sync_thread()
        start = time.perf_counter()
        image = mi.render(self.scene, sensor=self.sensor, integrator=integrator, spp=int(spp), seed=int(seed))
        array = np.array(image, dtype=np.float32)
        dr.sync_thread()
        seconds = time.perf_counter() - start
        channels = array.shape[-1]
        if channels < 7:
            raise RuntimeError(f"Mitsuba's aov integrator returned {channels} channels, expected albedo, normal and depth (7)")
        buffers = {"albedo": array[..., -7:-4], "normal": array[..., -4:-1], "depth": array[..., -1]}
        return buffers, seconds


#: Per-sample quantities :meth:`MitsubaScene.sample_pixels` can return beside the path contributions.
#: ``primary_depth``: camera-space depth (along the optical axis) of the camera ray's hit, ``inf`` for a miss;
#: ``primary_normal`` (3): its shading normal; ``diffuse_albedo`` (3): its BSDF's diffuse reflectance;
#: ``secondary_distance``: length of the ray sampled at the first vertex to its hit, ``inf`` for none;
#: ``secondary_diffuse``: that ray was sampled from a diffuse lobe; ``lens_u``, ``lens_v``: the lens sample
#: in primary sample space (thin lens only); ``camera_emission`` (3): the part of the contribution that is
#: emission seen directly by the camera ray (0 where the layout does not count it).
AUXILIARY_QUANTITIES = ("primary_depth", "primary_normal", "diffuse_albedo", "secondary_distance",
                        "secondary_diffuse", "lens_u", "lens_v", "camera_emission")

#: Per-pixel statistics :meth:`MitsubaScene.sample_pixel_statistics` reduces, and their reduction.
#: ``rgb`` / ``rgb_squared``: the path contribution and its square; ``diffuse_rgb``: the contribution of samples
#: whose secondary ray came from a diffuse lobe; ``albedo``, ``normal``: the camera hit's diffuse reflectance and
#: shading normal; ``depth``, ``hits``: the camera hit's depth and 1 (0 for a miss); ``nearest``, ``farthest``:
#: the camera hit's depth (``inf`` for a miss); ``shortest``: the diffuse-lobe secondary ray's length (``inf``
#: otherwise).
#: Each reduction as the numpy ufunc that merges two partial results, and its identity.
REDUCTIONS = {"sum": (np.add, 0.0), "min": (np.minimum, np.inf), "max": (np.maximum, -np.inf)}
PIXEL_STATISTICS = {"rgb": "sum", "rgb_squared": "sum", "diffuse_rgb": "sum", "albedo": "sum", "normal": "sum",
                    "depth": "sum", "hits": "sum", "nearest": "min", "farthest": "max", "shortest": "min"}


def _statistic_quantity(name, value, recorded):
    """The per-sample quantity behind a :data:`PIXEL_STATISTICS` name."""
    depth = recorded["primary_depth"]
    if name == "rgb":
        return value
    if name == "rgb_squared":
        return value * value
    if name == "diffuse_rgb":
        return dr.select(recorded["secondary_diffuse"], value, 0.0)
    if name == "albedo":
        return recorded["diffuse_albedo"]
    if name == "normal":
        return recorded["primary_normal"]
    if name == "depth":
        return dr.select(dr.isfinite(depth), depth, 0.0)
    if name == "hits":
        return dr.select(dr.isfinite(depth), mi.Float(1.0), mi.Float(0.0))
    if name in ("nearest", "farthest"):
        return mi.Float(depth)
    return dr.select(recorded["secondary_diffuse"], recorded["secondary_distance"], dr.inf)  # shortest


def _stacked(channels):
    """Evaluated Dr.Jit channels as float64 ``(n,)`` (one) or ``(n, 3)`` (three)."""
    arrays = [np.asarray(channel, dtype=np.float64) for channel in channels]
    return arrays[0] if len(arrays) == 1 else np.stack(arrays, axis=1)


GRADIENT_SHIFTS = {4: ((1, 0), (-1, 0), (0, 1), (0, -1)), 2: ((1, 0), (0, 1))}  # (dx, dy) per offset path
GRADIENT_LANE_LIMIT = 1 << 23  # lanes (base and offset paths) per gradient-domain launch


def gradient_paths(width, height, offsets):
    """Paths traced per base sample per pixel of a ``width`` x ``height`` film: every base path, and every offset
    of :data:`GRADIENT_SHIFTS` ``[offsets]`` that lands inside the film (``5 w h - 2 (w + h)`` for 4 offsets)."""
    return width * height + sum((width - abs(dx)) * (height - abs(dy)) for dx, dy in GRADIENT_SHIFTS[offsets])
GUIDED_STREAM = 0x9E37  # PCG32 stream of guided renders, apart from the signal and pixel-sample streams


def _lanes(count, spp, seed, *, first=0, stream=0, items=None, order=None):
    """One lane per sample: ``spp`` samples of each of ``count`` items (cells or pixels) from ``first``.

    With ``items`` (a ``mi.UInt32`` of ``count`` item numbers) the items are
    those instead of the run ``first, first + 1, ...``. With ``order`` (a
    ``mi.UInt32`` permutation of the ``count * spp`` sample numbers) lane
    ``i`` draws sample ``order[i]``: the same samples in another order.

    Returns ``(item, generator, lanes)``. Each lane's PCG32 is seeded with a
    TEA hash of (item, sample index, seed), so a sample's random numbers are a
    pure function of those, whatever the batching; ``stream`` separates
    estimators that must not share numbers. Sizes and seeds enter the kernel
    as opaque values: one compiled kernel serves every call.
    """
    lanes = int(count) * int(spp)
    index = dr.arange(mi.UInt32, lanes) if order is None else order
    samples_per_item = dr.opaque(mi.UInt32, int(spp))
    if items is None:
        item = dr.opaque(mi.UInt32, int(first)) + index // samples_per_item
    else:
        item = dr.gather(mi.UInt32, items, index // samples_per_item)
    sample_index = index % samples_per_item
    return item, _seeded_generator(item, sample_index, seed, stream), lanes


def _seeded_generator(item, sample_index, seed, stream):
    """The PCG32 of each lane, seeded with a TEA hash of (item, sample index, seed) on ``stream``."""
    seed_value = dr.opaque(mi.UInt32, int(seed))
    generator = mi.PCG32()
    generator.seed(mi.sample_tea_64(item, (sample_index << 16) ^ seed_value), mi.UInt64(seed_value) + stream)
    return generator


def _explicit_lanes(items, sample_indices, seed, *, stream=0):
    """Lanes for explicit (item, sample index) pairs, seeded exactly as :func:`_lanes` seeds them."""
    item = mi.UInt32(np.ascontiguousarray(items, dtype=np.uint32))
    sample_index = mi.UInt32(np.ascontiguousarray(sample_indices, dtype=np.uint32))
    return item, _seeded_generator(item, sample_index, seed, stream)


def _pss_vector(layout, grid_shape, generator, pixel_x, pixel_y, film_size):
    """One PSS vector per lane from its PCG32, the image-plane dimensions jittered in film pixel ``(pixel_x, pixel_y)``.

    Returns ``(samples, cell)``: name -> ``mi.Float`` for every dimension of
    ``layout``, and the flat C-order grid cell of each lane. The random
    numbers are drawn in ``layout.dimensions`` order whatever the pixel: a
    lane seeded like another but given a neighbouring pixel replays its
    numbers there (the gradient-domain shift, :meth:`MitsubaScene.sample_gradients`).
    """
    film_width, film_height = film_size
    strides = np.cumprod((1,) + tuple(grid_shape[:0:-1]))[::-1]
    axis_of = {name: position for position, name in enumerate(layout.axes)}
    samples = {}
    cell = mi.UInt32(0)
    for name in layout.dimensions:
        uniform = generator.next_float32()
        if name == "x":
            uniform = _in_pixel(pixel_x, uniform, film_width)
        elif name == "y":
            uniform = _in_pixel(pixel_y, uniform, film_height)
        if name in axis_of:
            position = axis_of[name]
            resolution = dr.opaque(mi.Float, float(grid_shape[position]))
            coordinate = dr.minimum(mi.UInt32(uniform * resolution), mi.UInt32(resolution) - 1)
            cell += coordinate * dr.opaque(mi.UInt32, int(strides[position]))
        samples[name] = uniform
    return samples, cell


def _in_pixel(pixel, uniform, size):
    """A coordinate in ``[0, 1)`` jittered by ``uniform`` inside pixel ``pixel`` of ``size`` pixels."""
    return dr.minimum((mi.Float(pixel) + uniform) * dr.opaque(mi.Float, 1.0 / size), ONE_MINUS_EPSILON)


def _zero_nonfinite(value, valid=None):
    """``value`` with NaN or infinite lanes (and lanes not ``valid``) set to 0, and the mask of kept lanes."""
    finite = dr.isfinite(value.x) & dr.isfinite(value.y) & dr.isfinite(value.z)
    if valid is not None:
        finite &= valid
    return dr.select(finite, value, 0.0), finite


def _count_false(mask):
    array = np.asarray(mask)
    return int(array.size - np.count_nonzero(array))


def _to_numpy(value):
    """An evaluated Dr.Jit scalar or 3-vector per lane as numpy: float32 ``(n,)`` / ``(n, 3)``, bool ``(n,)``."""
    if isinstance(value, mi.Bool):
        return np.asarray(value, dtype=bool)
    if dr.size_v(value) == 3:
        return _rgb_array((value.x, value.y, value.z))
    return np.asarray(value, dtype=np.float32)


def _rgb_array(channels):
    """Three evaluated Dr.Jit channels as a float32 ``(n, 3)`` array."""
    return np.stack([np.asarray(channel, dtype=np.float32) for channel in channels], axis=1)


def _warp_axes(map_shape, tables, uniforms, names, prefix, first_axis):
    """Warp ``uniforms[names[k]]`` for ``k >= first_axis`` through the map's conditional CDFs, in place.

    One binary search per axis in the CDF row of the cells chosen so far; the
    remainder of the uniform inside the chosen interval is the jitter inside
    the cell. Returns the flat cell index (C order over ``map_shape``).
    """
    for axis in range(first_axis, len(map_shape)):
        name = names[axis]
        length = int(map_shape[axis])
        table = mi.Float(np.ascontiguousarray(tables[axis], dtype=np.float32).reshape(-1))
        base = prefix * length
        value = uniforms[name]
        found = dr.binary_search(0, length - 1, lambda j: dr.gather(mi.Float, table, base + j) <= value)
        found = dr.minimum(found, length - 1)
        high = dr.gather(mi.Float, table, base + found)
        low = dr.select(found > 0, dr.gather(mi.Float, table, base + dr.maximum(found, 1) - 1), 0.0)
        width = high - low
        remainder = dr.clip(dr.select(width > 0, (value - low) / width, 0.5), 0.0, ONE_MINUS_EPSILON)
        uniforms[name] = dr.minimum((mi.Float(found) + remainder) * (1.0 / length), ONE_MINUS_EPSILON)
        prefix = base + found
    return prefix


def warp_points(map_shape, tables, uniforms, *, image_cells=None):
    """Run the guided renderer's in-kernel warp on explicit uniforms (for tests and diagnostics).

    Parameters
    ----------
    map_shape : tuple of int
    tables : list of ndarray
        :meth:`ImportanceMap.level_tables`.
    uniforms : ndarray, shape (n, D - first axis)
        Uniform numbers for the warped axes.
    image_cells : ndarray of int, optional
        Flat image-plane cells (the first two axes) to condition on; without
        them every axis is warped.

    Returns
    -------
    points : ndarray, shape like ``uniforms``
    cells : ndarray of int64, shape (n,)
        Flat cell of each point over the whole map.
    """
    initialize()
    first_axis = 0 if image_cells is None else 2
    names = [f"axis{k}" for k in range(len(map_shape))]
    values = {names[first_axis + k]: mi.Float(np.ascontiguousarray(uniforms[:, k], dtype=np.float32))
              for k in range(uniforms.shape[1])}
    if image_cells is None:
        prefix = dr.zeros(mi.UInt32, uniforms.shape[0])
    else:
        prefix = mi.UInt32(np.asarray(image_cells, dtype=np.uint32))
    cells = _warp_axes(map_shape, tables, values, names, prefix, first_axis)
    dr.eval(cells, *values.values())
    points = np.stack([np.asarray(values[names[first_axis + k]], dtype=np.float64) for k in range(uniforms.shape[1])], 1)
    return points, np.asarray(cells, dtype=np.int64)


def _power_heuristic(pdf_a, pdf_b):
    a2 = dr.square(pdf_a)
    b2 = dr.square(pdf_b)
    weight = a2 / (a2 + b2)
    return dr.select(dr.isfinite(weight), weight, 0.0)


def exr_bytes(image):
    """A float32 ``(height, width, 3)`` image as OpenEXR file bytes (Mitsuba's Bitmap, written to memory)."""
    initialize()
    bitmap = mi.Bitmap(np.ascontiguousarray(image, dtype=np.float32), pixel_format=mi.Bitmap.PixelFormat.RGB)
    stream = mi.MemoryStream()
    bitmap.write(stream, mi.Bitmap.FileFormat.OpenEXR)
    return bytes(stream.raw_buffer())[:stream.size()]


def write_exr(path, image):
    """Write a float32 ``(height, width, 3)`` image as OpenEXR, atomically (a full disk names the file)."""
    from ..provenance import atomic_write_bytes

    atomic_write_bytes(path, exr_bytes(image))

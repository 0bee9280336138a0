"""A scene loaded into Mitsuba with a sensor at a given resolution; its estimators live in their own modules."""

from __future__ import annotations

import dataclasses
import sys

import numpy as np

from ..scenes import note_once
from .cells import sample_cells
from .gradients import sample_gradients
from .guided import render_estimator, render_guided
from .integrand import emitter_area_table, intersect
from .integrators import render_aovs, render_path
from .path_classes import render_path_classes
from .pixel_statistics import sample_pixel_statistics
from .pixels import sample_pixels
from .runtime import initialize, modules
from .scene_dictionaries import (coherent_camera_rays, camera_from_sensor, load_scene_file, principal_point_offset,
                                 sensor_dictionary, to_mitsuba_dict, to_mitsuba_transform)


def _note_unused_sensor_settings(spec, sensors, principal_point, thin_lens):
    """Say on standard error, once per file, what of the file's sensors sparselt does not use: a film's crop window
    (sparselt's sensor is the whole film, every method's, PT's and the reference's alike), sensors after the first,
    and a principal point offset under a thin lens (Mitsuba's ``thinlens`` has none)."""
    film = sensors[0].film()
    size, crop, offset = (tuple(int(v) for v in values) for values in (film.size(), film.crop_size(),
                                                                         film.crop_offset()))
    if crop != size:
        note_once(spec.filename, "crop",
                  f"the film of {spec.name!r} has a crop window ({crop[0]}x{crop[1]} at {offset[0]},{offset[1]}); "
                  f"sparselt renders the whole {size[0]}x{size[1]} film (every method, PT and the reference alike): "
                  "crop its images afterwards")
    if len(sensors) > 1:
        names = ", ".join(repr(sensor.id()) for sensor in sensors)
        note_once(spec.filename, "sensors",
                  f"{spec.name!r} has {len(sensors)} sensors ({names}); sparselt renders through the first one the "
                  "file lists")
    if thin_lens and any(principal_point):
        note_once(spec.filename, "principal point",
                  f"the camera of {spec.name!r} has a principal point offset ({principal_point[0]:g}, "
                  f"{principal_point[1]:g}) that a thin lens cannot keep (Mitsuba's thinlens has none): sparselt "
                  "renders the centred view (every method, PT and the reference alike)")


class MitsubaScene:
    """A scene loaded into Mitsuba with a sensor at a given resolution.

    Loading (a built-in scene's dictionary or a scene file), the thin lens's
    autofocus and the camera's geometry live here; each estimator method
    hands itself to its module (:mod:`~sparselt.rendering.mitsuba.cells`,
    :mod:`~sparselt.rendering.mitsuba.pixels`,
    :mod:`~sparselt.rendering.mitsuba.pixel_statistics`,
    :mod:`~sparselt.rendering.mitsuba.gradients`,
    :mod:`~sparselt.rendering.mitsuba.guided`,
    :mod:`~sparselt.rendering.mitsuba.path_classes`,
    :mod:`~sparselt.rendering.mitsuba.integrators`), which launches through
    :func:`~sparselt.rendering.mitsuba.launch.launch`.

    Parameters
    ----------
    spec : SceneSpec
        Built-in scene or scene file (see :func:`sparselt.rendering.scenes.get_scene`).
    resolution : tuple of int
        Film ``(width, height)``.
    variant : str, optional
        Mitsuba variant (default ``llvm_ad_rgb``).

    Attributes
    ----------
    scene : mitsuba.Scene
    sensor : mitsuba.Sensor
        The film's sensor: box filter, ``width`` x ``height``.
    camera : Camera
        The camera as sampled (lens and focus resolved).
    coherent_camera_rays : bool
        Whether camera rays are traced as coherent packets
        (:func:`~sparselt.rendering.mitsuba.scene_dictionaries.coherent_camera_rays`).
    emitter_areas : mi.Float
        :func:`~sparselt.rendering.mitsuba.integrand.emitter_area_table` of the scene.
    """

    def __init__(self, spec, resolution, *, variant=None):
        mi = initialize(variant)
        self.spec = spec
        self.width, self.height = (int(v) for v in resolution)
        if spec.filename is not None:
            self.scene = load_scene_file(spec)
            sensors = self.scene.sensors()
            if not sensors:
                raise ValueError(f"scene file {spec.filename!r} has no sensor to take the camera from")
            base_camera = camera_from_sensor(sensors[0])
            principal_point = principal_point_offset(sensors[0])
        else:
            self.scene = mi.load_dict(to_mitsuba_dict(spec.objects))
            base_camera = spec.camera
            principal_point = (0.0, 0.0)
        self.camera = spec.resolved_camera(base_camera)
        if spec.filename is not None:
            _note_unused_sensor_settings(spec, sensors, principal_point, self.camera.thin_lens)
        if spec.focuses_on_the_scene(base_camera):
            self.camera = self._focus_on_central_hit(self.camera)
        #: The file's principal point offset (a fraction of the film, as Mitsuba's perspective sensor takes it),
        #: kept by a pinhole camera; (0, 0) for built-in scenes.
        self.principal_point = (0.0, 0.0) if self.camera.thin_lens else principal_point
        self.sensor = mi.load_dict(sensor_dictionary(self.camera, self.width, self.height,
                                                     principal_point=self.principal_point))
        self.coherent_camera_rays = coherent_camera_rays(self.camera)
        self.emitter_areas = emitter_area_table(self.scene)

    def _focus_on_central_hit(self, camera):
        """``camera`` focused at the distance where the ray through the image centre hits the scene.

        A ray that hits nothing keeps the camera's focus distance, with a note
        on standard error.
        """
        mi, _ = modules()
        pinhole = mi.load_dict(sensor_dictionary(dataclasses.replace(camera, aperture_radius=None), 1, 1))
        ray, _ = pinhole.sample_ray(time=0.0, sample1=0.5, sample2=mi.Point2f(0.5, 0.5), sample3=mi.Point2f(0.5, 0.5))
        interaction = intersect(self.scene, ray)
        # Mitsuba's thin lens focuses on a plane at focus_distance along the camera's local z axis.
        hit = [float(np.ravel(np.asarray(coordinate))[0]) for coordinate in interaction.p]
        distance = float((to_mitsuba_transform(camera.to_world).inverse() @ mi.ScalarPoint3f(hit))[2])
        if not bool(np.ravel(np.asarray(interaction.is_valid()))[0]) or not (0 < distance < float("inf")):
            print(f"sparselt: note: the central ray of the camera of {self.spec.name!r} hits nothing; the thin lens "
                  f"focuses at the camera's own focus distance {camera.focus_distance:g} (give --focus-distance to "
                  "choose)", file=sys.stderr)
            return camera
        return camera.with_lens(focus_distance=distance)

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
        mi, _ = modules()
        parameters = mi.traverse(self.sensor)
        fov = float(np.ravel(np.asarray(parameters["x_fov"]))[0])
        return self.width / (2.0 * np.tan(np.radians(fov) / 2.0))

    # -- estimators of primary sample space, each in its module (the methods' names are the modules' functions)

    def sample_cells(self, layout, grid_shape, first_cell, cell_count, spp, seed, *, cells=None):
        """:func:`sparselt.rendering.mitsuba.cells.sample_cells` on this scene."""
        return sample_cells(self, layout, grid_shape, first_cell, cell_count, spp, seed, cells=cells)

    def sample_pixels(self, layout, grid_shape, spp, seed, first_pixel=0, pixel_count=None, resolution=None,
                      auxiliary=(), lanes=None, cells=True):
        """:func:`sparselt.rendering.mitsuba.pixels.sample_pixels` on this scene."""
        return sample_pixels(self, layout, grid_shape, spp, seed, first_pixel=first_pixel, pixel_count=pixel_count,
                             resolution=resolution, auxiliary=auxiliary, lanes=lanes, cells=cells)

    def sample_pixel_statistics(self, layout, grid_shape, seed, names, *, spp=None, counts=None, halves=False,
                                first_sample=0):
        """:func:`sparselt.rendering.mitsuba.pixel_statistics.sample_pixel_statistics` on this scene."""
        return sample_pixel_statistics(self, layout, grid_shape, seed, names, spp=spp, counts=counts, halves=halves,
                                       first_sample=first_sample)

    def sample_gradients(self, layout, grid_shape, spp, seed, *, offsets=4, shift="replay", halves=False,
                         albedo=True):
        """:func:`sparselt.rendering.mitsuba.gradients.sample_gradients` on this scene."""
        return sample_gradients(self, layout, grid_shape, spp, seed, offsets=offsets, shift=shift, halves=halves,
                                albedo=albedo)

    def render_estimator(self, layout, spp, seed):
        """:func:`sparselt.rendering.mitsuba.guided.render_estimator` on this scene."""
        return render_estimator(self, layout, spp, seed)

    def render_guided(self, layout, map_shape, tables, densities, spp, seed, *, mode):
        """:func:`sparselt.rendering.mitsuba.guided.render_guided` on this scene."""
        return render_guided(self, layout, map_shape, tables, densities, spp, seed, mode=mode)

    def render_path_classes(self, spp, max_depth, seed=0):
        """:func:`sparselt.rendering.mitsuba.path_classes.render_path_classes` on this scene."""
        return render_path_classes(self, spp, max_depth, seed)

    # -- Mitsuba's own integrators ---------------------------------------------

    def render_path(self, spp, max_depth, seed=0):
        """:func:`sparselt.rendering.mitsuba.integrators.render_path` on this scene."""
        return render_path(self, spp, max_depth, seed)

    def render_aovs(self, spp, seed=0):
        """:func:`sparselt.rendering.mitsuba.integrators.render_aovs` on this scene."""
        return render_aovs(self, spp, seed)

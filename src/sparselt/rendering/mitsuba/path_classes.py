"""Radiance per path class: each pixel's total radiance and the part of it carried by caustic paths.

:func:`render_path_classes` traces the paths of Mitsuba's ``path``
integrator (next-event estimation and BSDF sampling, combined by the power
heuristic; no Russian roulette) and sorts every contribution by the path it
belongs to, in the same kernel. It works on every loaded scene, a scene file
included: the classes come from the BSDF components the paths sample, not
from the scene's description.

References
----------
P. S. Heckbert, "Adaptive radiosity textures for bidirectional ray
tracing", SIGGRAPH 1990 (the ``L S+ D (S|D)* E`` notation of caustic
paths); E. Veach, "Robust Monte Carlo methods for light transport
simulation" (1997), 9.2 (multiple importance sampling).
"""

from __future__ import annotations

import numpy as np

from ...checks import check_integer
from .integrand import intersect, power_heuristic, zero_nonfinite
from .lanes import in_pixel, item_lanes
from .launch import launch
from .readback import count_false, rgb_array
from .runtime import modules

#: The images :func:`render_path_classes` returns: ``total`` (every path) and ``caustic`` (paths ``L S+ D (S|D)* E``).
PATH_CLASSES = ("total", "caustic")

#: PCG32 stream of the path-class renders, apart from the signal, pixel-sample and guided streams.
PATH_CLASSES_STREAM = 0xCA05

#: Most lanes (path samples) one kernel traces; a larger render runs in pieces of whole pixels.
LANES_PER_KERNEL = 1 << 22


def render_path_classes(scene, spp, max_depth, seed=0):
    """Each pixel's radiance, in total and over caustic paths only, ``spp`` samples per pixel.

    Parameters
    ----------
    scene : MitsubaScene
    spp : int
        Samples per pixel, at least 1.
    max_depth : int
        Longest path in Mitsuba's convention (1: emitters seen directly; 2:
        direct lighting; ...), at least 1, as
        :func:`~sparselt.rendering.mitsuba.integrators.render_path`.
    seed : int, optional
        Any non-negative integer (:func:`~sparselt.rendering.mitsuba.launch.fold_seed`).

    Returns
    -------
    images : dict
        Each name of :data:`PATH_CLASSES` -> ndarray of shape (height, width,
        3), float32: ``total``, an unbiased estimate of the image of
        Mitsuba's ``path`` integrator at ``max_depth`` (the scene's emitter
        visibility), and ``caustic``, the part of the same estimate carried by
        caustic paths (``caustic <= total`` sample by sample).
    nonfinite : int
        Samples that were NaN or infinite (counted as 0 in both images).

    Raises
    ------
    TypeError, ValueError
        ``spp`` or ``max_depth`` is not an integer of at least 1, or ``seed``
        is not a non-negative integer, before anything renders.

    Notes
    -----
    A vertex is *specular* (``S``) when the BSDF component sampled there is
    a Dirac delta (Mitsuba's ``BSDFFlags.Delta``: ``DeltaReflection``,
    ``DeltaTransmission`` or ``Null``; a smooth conductor or dielectric, a
    smooth plastic's coat, a thin dielectric, whose transmission Mitsuba
    flags ``Null``, a ``null`` surface) and *diffuse* (``D``) otherwise:
    glossy components count as diffuse, however low their roughness. A
    ``Null`` pass-through counts as specular because the ``path``
    integrator's shadow rays stop at such a surface too: light through it is
    found by BSDF sampling alone, exactly as light through glass.

    A path is caustic when its light end is ``L S+ D``: read from the
    camera, a diffuse vertex, then one or more specular ones, then the
    emitter (Heckbert's ``L S+ D (S|D)* E``; what lies between the camera and
    that diffuse vertex does not matter). An eye-traced path tracer finds
    such a path only by BSDF sampling: next-event estimation connects a
    smooth component to the emitter, so its light end is ``L D``, and an
    emitter seen directly (``L E``) or through specular vertices only
    (``L S+ E``) is no caustic. A contribution is therefore caustic exactly
    when it is an emitter hit by BSDF sampling whose last vertex is specular
    and some earlier vertex on the path is diffuse. Such a hit has MIS weight
    1 (the emitter cannot be sampled towards a delta direction), so the
    caustic image is an unbiased estimate of the caustic paths' radiance and
    the rest of ``total`` of the others'. Emitters that are points or
    directions (``point``, ``spot``, ``directional``) are never hit, so their
    light forms no caustic here, as in every eye-traced path tracer.

    The random numbers of a sample are a pure function of (seed, pixel,
    sample index), on their own PCG32 stream (:data:`PATH_CLASSES_STREAM`),
    whatever the pieces the render runs in (:data:`LANES_PER_KERNEL`).
    """
    spp = check_integer("spp", spp, 1)
    max_depth = check_integer("max_depth", max_depth, 1)
    pixels = scene.width * scene.height
    pixels_per_kernel = max(1, LANES_PER_KERNEL // spp)

    def work(folded_seed):
        sums = np.zeros((pixels, 2, 3), dtype=np.float32)
        nonfinite = 0
        for first in range(0, pixels, pixels_per_kernel):
            count = min(pixels_per_kernel, pixels - first)
            part, part_nonfinite = _render_pixels(scene, spp, max_depth, folded_seed, first, count)
            sums[first:first + count] = part
            nonfinite += part_nonfinite
        images = {name: sums[:, index].reshape(scene.height, scene.width, 3)
                  for index, name in enumerate(PATH_CLASSES)}
        return images, nonfinite

    return launch(work, seed, path_samples=pixels * spp)


def _render_pixels(scene, spp, max_depth, seed, first, count):
    """Means of ``count`` pixels from ``first``: (count, 2, 3) float32 (total, caustic), and the nonfinite count."""
    mi, dr = modules()
    pixel, generator, _ = item_lanes(count, spp, seed, first=first, stream=PATH_CLASSES_STREAM)
    width = dr.opaque(mi.UInt32, scene.width)
    position = mi.Point2f(in_pixel(pixel % width, generator.next_float32(), scene.width),
                          in_pixel(pixel // width, generator.next_float32(), scene.height))
    aperture = mi.Point2f(generator.next_float32(), generator.next_float32())
    total, caustic = _trace(scene, max_depth, position, aperture, generator)
    total, finite = zero_nonfinite(total)
    caustic = dr.select(finite, caustic, 0.0)
    scale = 1.0 / spp
    channels = (total.x, total.y, total.z, caustic.x, caustic.y, caustic.z)
    dr.eval(channels, finite)
    means = [dr.block_sum(channel, spp) * scale for channel in channels]
    dr.eval(means)
    return rgb_array(means).reshape(count, 2, 3), count_false(finite)


def _trace(scene, max_depth, position, aperture, generator):
    """The path integrator's estimate of each lane and its caustic part (see :func:`render_path_classes`)."""
    mi, dr = modules()
    context = mi.BSDFContext()
    world = scene.scene
    ray, ray_weight = scene.sensor.sample_ray(time=0.0, sample1=0.5, sample2=position, sample3=aperture)
    throughput = mi.Color3f(ray_weight)
    total = mi.Color3f(0.0)
    caustic = mi.Color3f(0.0)
    active = mi.Bool(True)
    interaction = intersect(world, ray, active, coherent=scene.coherent_camera_rays)
    if not scene.spec.hide_emitters:
        total += throughput * interaction.emitter(world).eval(interaction, active)
    # The path's light end so far: some vertex was diffuse; the last vertex is specular and a diffuse one comes
    # before it (so an emitter hit now closes a caustic path).
    seen_diffuse = mi.Bool(False)
    caustic_chain = mi.Bool(False)

    for _ in range(1, max_depth):
        active &= interaction.is_valid()
        bsdf = interaction.bsdf(ray)

        # Next-event estimation: a smooth component to the emitter, never caustic.
        light_sample = mi.Point2f(generator.next_float32(), generator.next_float32())
        active_light = active & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        direction_sample, emitter_weight = world.sample_emitter_direction(interaction, light_sample, True,
                                                                          active_light)
        active_light &= direction_sample.pdf != 0.0
        bsdf_value, bsdf_pdf = bsdf.eval_pdf(context, interaction, interaction.to_local(direction_sample.d),
                                             active_light)
        weight = dr.select(direction_sample.delta, 1.0, power_heuristic(direction_sample.pdf, bsdf_pdf))
        total += dr.select(active_light, throughput * weight * bsdf_value * emitter_weight, 0.0)

        # BSDF sampling, and the emitter the sampled ray hits.
        lobe = generator.next_float32()
        direction = mi.Point2f(generator.next_float32(), generator.next_float32())
        bsdf_sample, bsdf_weight = bsdf.sample(context, interaction, lobe, direction, active)
        throughput = dr.select(active, throughput * bsdf_weight, 0.0)
        active &= dr.max(throughput) > 0.0
        specular = mi.has_flag(bsdf_sample.sampled_type, mi.BSDFFlags.Delta)
        caustic_chain = specular & seen_diffuse
        seen_diffuse |= ~specular

        ray = interaction.spawn_ray(interaction.to_world(bsdf_sample.wo))
        next_interaction = intersect(world, ray, active)
        emitter_sample = mi.DirectionSample3f(world, si=next_interaction, ref=interaction)
        emission = emitter_sample.emitter.eval(next_interaction, active)
        light_pdf = world.pdf_emitter_direction(interaction, emitter_sample, active & ~specular)
        hit = dr.select(active, throughput * emission * power_heuristic(bsdf_sample.pdf, light_pdf), 0.0)
        total += hit
        caustic += dr.select(caustic_chain, hit, 0.0)
        interaction = next_interaction
    return total, caustic

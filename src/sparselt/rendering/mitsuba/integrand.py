"""The integrand: the path contribution ``f(S(u))`` of explicit primary-sample-space vectors ``u``.

Every estimator of :mod:`sparselt.rendering.mitsuba` evaluates
:func:`path_contribution` on the vectors its lanes draw
(:mod:`~sparselt.rendering.mitsuba.lanes`), laid out by a
:class:`~sparselt.rendering.layout.PathLayout`; the per-sample auxiliary
outputs (:data:`AUXILIARY_QUANTITIES`) come from the same kernel.

References
----------
Thesis 2.1.6 and 3.2.2 (the path integral in primary sample space); E. Veach,
"Robust Monte Carlo methods for light transport simulation" (1997), 9.2
(multiple importance sampling, the power heuristic).
"""

from __future__ import annotations

import numpy as np

from .readback import to_device
from .runtime import modules

#: Per-sample quantities :meth:`MitsubaScene.sample_pixels` can return beside the path contributions.
#: ``primary_depth``: camera-space depth (along the optical axis) of the camera ray's hit, ``inf`` for a miss;
#: ``primary_normal`` (3): its shading normal; ``diffuse_albedo`` (3): its BSDF's diffuse reflectance;
#: ``secondary_distance``: length of the ray sampled at the first vertex to its hit, ``inf`` for none;
#: ``secondary_diffuse``: that ray was sampled from a diffuse lobe; ``lens_u``, ``lens_v``: the lens sample
#: in primary sample space (thin lens only); ``camera_emission`` (3): the part of the contribution that is
#: emission seen directly by the camera ray (0 where the layout does not count it); ``direct_light`` (3): the
#: first vertex's direct lighting, the part of the contribution of the paths that end at a light reached from
#: the first vertex (its next-event estimate plus the MIS-weighted emission its BSDF ray finds);
#: ``light_distance``: ``d1``, the distance from the first vertex to its light sample (``inf`` without one);
#: ``occluder_distance``: ``d2``, the distance from that light point to the nearest blocker of the shadow ray
#: (``inf`` where it is not blocked); ``light_size``: ``sigma_l = sqrt(A) / 2`` of the sampled emitter's shape
#: of area ``A`` (0 for lights without a shape). The last three are the soft-shadow analysis's inputs (Mehta et
#: al. 2012, 3); the blocker's ray is traced only where ``occluder_distance`` is evaluated (Dr.Jit is lazy).
#: ``path_vertices``: the vertices the path reached (the camera ray's hit and each bounce's hit; 0 for a camera
#: ray that misses), the axis-aligned filters' cost model.
AUXILIARY_QUANTITIES = ("primary_depth", "primary_normal", "diffuse_albedo", "secondary_distance",
                        "secondary_diffuse", "lens_u", "lens_v", "camera_emission", "direct_light", "light_distance",
                        "occluder_distance", "light_size", "path_vertices")


def path_contribution(scene, layout, samples, auxiliary=None):
    """Radiance of the paths defined by explicit PSS samples.

    Parameters
    ----------
    scene : MitsubaScene
        Its Mitsuba scene, sensor and camera-ray mode.
    layout : PathLayout
        Which vertices sample lights and which emission hits count (see
        :mod:`sparselt.rendering.layout`).
    samples : dict
        Each name in ``layout.dimensions`` -> a ``mi.Float`` per lane.
    auxiliary : dict, optional
        Receives the per-sample quantities of :data:`AUXILIARY_QUANTITIES`
        computed in the same kernel (the frequency-analysis filters' inputs,
        Mehta et al. 2012-2014).

    Returns
    -------
    mi.Color3f
        The contribution of each lane.

    Notes
    -----
    The estimator follows Mitsuba's ``path`` integrator (MIS with the power
    heuristic between next-event estimation and BSDF sampling) without
    Russian roulette.
    """
    mi, dr = modules()
    context = mi.BSDFContext()
    world = scene.scene
    ray, throughput, interaction = camera_hit(scene, layout, samples)
    result = mi.Color3f(0.0)
    active = mi.Bool(True)
    if auxiliary is not None:
        _record_primary(scene.sensor, auxiliary, interaction, samples, layout)
    if layout.count_camera_emission:
        result += throughput * interaction.emitter(world).eval(interaction, active)
        if auxiliary is not None:
            auxiliary["camera_emission"] = mi.Color3f(result)

    vertices = dr.select(interaction.is_valid(), mi.Float(1.0), mi.Float(0.0))
    for index, plan in enumerate(layout.vertices, start=1):
        first = auxiliary is not None and index == 1
        parts = {} if first else None
        result, next_interaction, ray, throughput, active, bsdf_sample = vertex_step(
            world, context, plan, index, samples, interaction, ray, throughput, active, result, parts=parts)
        if first:
            _record_direct(world, scene.emitter_areas, auxiliary, interaction, parts)
            hit = active & next_interaction.is_valid()
            auxiliary["secondary_distance"] = dr.select(hit, next_interaction.t, dr.inf)
            auxiliary["secondary_diffuse"] = mi.has_flag(bsdf_sample.sampled_type, mi.BSDFFlags.Diffuse)
        vertices += dr.select(active & next_interaction.is_valid(), mi.Float(1.0), mi.Float(0.0))
        interaction = next_interaction
    if auxiliary is not None:
        auxiliary["path_vertices"] = vertices
    return result


#: Shape types whose hits need no guard in :func:`intersect` (Mitsuba's ``ShapeType`` names); any other shape in
#: a scene (a curve, an instance whose group may hold curves) turns the guard on.
PLAIN_SHAPE_TYPES = frozenset({"Mesh", "Rectangle", "Cylinder", "Disk", "Sphere", "SDFGrid", "Ellipsoids",
                               "EllipsoidsMesh"})
#: Curve shapes: :func:`intersect` keeps their hits' segment parameter this many float32 ulps (of the segment's
#: index + 1) below 1.
CURVE_PARAMETER_MARGIN = 2.0


def intersect(world, ray, active=True, *, coherent=False):
    """The surface interaction of each lane's ``ray`` with ``world`` (every ``RayFlags.All`` field), as
    ``world.ray_intersect(ray, RayFlags.All, coherent, active)`` returns it, except on curves' segment ends.

    Every surface interaction this package computes goes through here
    (the visibility tests, ``ray_test`` and the light samples' shadow rays,
    compute none and are Mitsuba's own). Mitsuba 3.9 (LLVM
    backend) reads one element past the end of a ``bsplinecurve``'s segment
    table for some hits: Dr.Jit's debug mode shows "out-of-bounds read from
    position 120 in an array of size 120" on the workshop scene's brush of
    120 segments, none without the brush, none with this guard. The hits
    themselves are on valid segments (the last, 119, with its parameter up
    to 0.99999595), and keeping the parameter off the segment's end removes
    the read: as far as measured, a parameter within float32 rounding of the
    last segment's end is taken to a global one and back and lands on
    segment 120. The value read is garbage; where it then
    indexes the control points, the process dies with a segmentation fault:
    ``pt`` on the workshop scene's indirect kind at 64 spp and seed 2^30 did,
    every time. So in a scene with curves (or instances, whose groups may
    hold them) the intersection is computed as its preliminary part and its
    surface interaction, and on curve hits the segment parameter ``u`` is
    kept :data:`CURVE_PARAMETER_MARGIN` float32 ulps of ``index + 1`` below
    1 (1.5e-5 of a segment at the 120th segment, 2.4e-4 at the 2000th).
    Elsewhere the result is ``Scene.ray_intersect``'s (the two-step form
    gives the same fields bit for bit: measured on courtyard, the
    greenhouse's instances and the workshop scene; ``t``, ``p``, ``n``, the
    shading frame, ``uv``, ``dp_du``, ``dp_dv``, ``wi``, the shape). Mitsuba's
    own ``path`` integrator (``pt`` on the path and dof kinds, the
    references) has no such guard.
    """
    mi, dr = modules()
    active = mi.Bool(active) if isinstance(active, bool) else active
    if not _has_unguarded_shapes(world):
        return world.ray_intersect(ray, mi.RayFlags.All, coherent, active)
    preliminary = world.ray_intersect_preliminary(ray, coherent, active)
    kind = preliminary.shape.shape_type()
    curve = (kind == int(mi.ShapeType.BSplineCurve.value)) | (kind == int(mi.ShapeType.LinearCurve.value))
    # The float32 ulp of index + 1: its exponent bits, as a float, times 2^-23.
    scale = dr.reinterpret_array(mi.Float, dr.reinterpret_array(mi.UInt32, mi.Float(preliminary.prim_index + 1))
                                 & 0x7F800000)
    bound = 1.0 - CURVE_PARAMETER_MARGIN * scale * 2.0 ** -23
    preliminary.prim_uv.x = dr.select(curve, dr.minimum(preliminary.prim_uv.x, bound), preliminary.prim_uv.x)
    return preliminary.compute_surface_interaction(ray, mi.RayFlags.All, active)


def _has_unguarded_shapes(world):
    """Whether ``world`` has a shape outside :data:`PLAIN_SHAPE_TYPES` (a curve, an instance)."""
    mi, _ = modules()
    plain = {int(mi.ShapeType.__members__[name].value) for name in PLAIN_SHAPE_TYPES}
    return any(int(shape.shape_type()) not in plain for shape in world.shapes())


def camera_hit(scene, layout, samples):
    """The camera ray of each lane's film (and lens) sample, its weight as a ``Color3f`` and its first hit."""
    mi, _ = modules()
    position = mi.Point2f(samples["x"], samples["y"])
    aperture = mi.Point2f(samples["lens_u"], samples["lens_v"]) if layout.thin_lens else mi.Point2f(0.5, 0.5)
    ray, ray_weight = scene.sensor.sample_ray(time=0.0, sample1=0.5, sample2=position, sample3=aperture)
    hit = intersect(scene.scene, ray, coherent=scene.coherent_camera_rays)
    return ray, mi.Color3f(ray_weight), hit


def vertex_step(world, context, plan, index, samples, interaction, ray, throughput, active, result, *, parts=None):
    """One vertex ``index`` of :func:`path_contribution`'s estimator, its contribution added to ``result``.

    Next-event estimation with the vertex's light sample (where ``plan``
    says so, :func:`next_event`), the BSDF sample, and the emission its ray
    finds (:func:`emission_found`).

    ``parts``, a dict, receives this vertex's terms (the same arithmetic,
    so ``result`` is bit for bit the same): ``light`` (the
    :func:`light_sample`, where ``plan`` does next-event estimation),
    ``next_event`` and ``emission`` (its two terms of ``result``, each
    absent where ``plan`` does not add it), ``light_attempted`` (the lanes
    that sampled a light, before the sample's density or visibility).

    Returns
    -------
    tuple
        ``(result, next_interaction, ray, throughput, active, bsdf_sample)``:
        the running sum with this vertex's contribution, the BSDF-sampled
        ray's hit, that ray, the throughput after the BSDF sample, the
        lanes still alive, and the BSDF sample record.
    """
    mi, dr = modules()
    active &= interaction.is_valid()
    bsdf = interaction.bsdf(ray)
    if plan.next_event:  # next_event's two steps, so that parts can keep the light sample
        light = light_sample(world, bsdf, interaction, samples, index, active)
        contribution = light_contribution(context, bsdf, interaction, light, throughput)
        if parts is not None:
            parts.update(light=light, next_event=contribution,
                         light_attempted=active & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth))
        result += contribution
    direction = mi.Point2f(samples[f"bsdf{index}_u"], samples[f"bsdf{index}_v"])
    bsdf_sample, bsdf_weight = bsdf.sample(context, interaction, samples[f"lobe{index}"], direction, active)
    throughput = dr.select(active, throughput * bsdf_weight, 0.0)
    active &= dr.max(throughput) > 0.0
    ray = interaction.spawn_ray(interaction.to_world(bsdf_sample.wo))
    next_interaction = intersect(world, ray, active)
    if plan.count_emission_hit:
        delta = mi.has_flag(bsdf_sample.sampled_type, mi.BSDFFlags.Delta)
        emission = emission_found(world, plan, interaction, next_interaction, bsdf_sample.pdf, delta, active)
        emission = dr.select(active, throughput * emission, 0.0)
        if parts is not None:
            parts["emission"] = emission
        result += emission
    return result, next_interaction, ray, throughput, active, bsdf_sample


def next_event(world, context, bsdf, interaction, samples, index, throughput, active):
    """Next-event estimation at vertex ``index``: its light sample's contribution, weighted by the power heuristic
    against BSDF sampling (Veach 1997, 9.2); 0 on lanes not ``active`` or on a delta BSDF."""
    light = light_sample(world, bsdf, interaction, samples, index, active)
    return light_contribution(context, bsdf, interaction, light, throughput)


def light_sample(world, bsdf, interaction, samples, index, active):
    """The emitter sample of vertex ``index`` (shadow ray traced): ``(direction sample, emitter weight, lanes it
    lights)``. It depends on the vertex's position only, not on the direction the path arrived from."""
    mi, _ = modules()
    sample = mi.Point2f(samples[f"light{index}_u"], samples[f"light{index}_v"])
    active_light = active & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
    direction_sample, emitter_weight = world.sample_emitter_direction(interaction, sample, True, active_light)
    active_light &= direction_sample.pdf != 0.0
    return direction_sample, emitter_weight, active_light


def light_contribution(context, bsdf, interaction, light, throughput):
    """The contribution of a :func:`light_sample` through ``bsdf`` at ``interaction`` (its ``wi``), with the power
    heuristic weight against BSDF sampling."""
    _, dr = modules()
    direction_sample, emitter_weight, active_light = light
    local_direction = interaction.to_local(direction_sample.d)
    bsdf_value, bsdf_pdf = bsdf.eval_pdf(context, interaction, local_direction, active_light)
    weight = dr.select(direction_sample.delta, 1.0, power_heuristic(direction_sample.pdf, bsdf_pdf))
    return dr.select(active_light, throughput * weight * bsdf_value * emitter_weight, 0.0)


def emission_found(world, plan, interaction, hit, bsdf_pdf, delta, active):
    """The emission at ``hit`` towards ``interaction`` (its ``wi``), found by a BSDF-sampled ray of density
    ``bsdf_pdf``: weighted by the power heuristic against next-event estimation where ``plan`` does it and the
    sample was not ``delta``, with weight one otherwise (Veach 1997, 9.2). Not multiplied by a throughput."""
    mi, _ = modules()
    emitter_sample = mi.DirectionSample3f(world, si=hit, ref=interaction)
    emission = emitter_sample.emitter.eval(hit, active)
    if plan.next_event:
        light_pdf = world.pdf_emitter_direction(interaction, emitter_sample, active & ~delta)
        emission *= power_heuristic(bsdf_pdf, light_pdf)
    return emission


def _record_primary(sensor, auxiliary, interaction, samples, layout):
    """The camera ray's hit: camera-space depth, shading normal, diffuse reflectance; the lens sample."""
    mi, dr = modules()
    origin, forward = camera_axis(sensor)
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
    auxiliary["direct_light"] = mi.Color3f(dr.zeros(mi.Float, dr.width(depth)))
    auxiliary["light_distance"] = dr.full(mi.Float, dr.inf, dr.width(depth))
    auxiliary["occluder_distance"] = dr.full(mi.Float, dr.inf, dr.width(depth))
    auxiliary["light_size"] = dr.zeros(mi.Float, dr.width(depth))


def _record_direct(world, emitter_areas, auxiliary, interaction, parts):
    """The first vertex's direct lighting and its light sample's soft-shadow geometry (:data:`AUXILIARY_QUANTITIES`).

    ``d1`` is the light sample's distance. Mitsuba returns a blocked light
    sample with density and weight 0 (but its point and distance kept): a
    sample of an area light that faces the receiver and has density 0 is
    a blocked candidate, and one more ray along the shadow segment finds
    the nearest blocker; ``d2`` is its distance from the light point
    (Mehta et al. 2012, 3: the light-occluder distance). The light's
    size is its shape's ``sigma_l = sqrt(A) / 2``: Mehta et al. (2012) model
    a planar light as a Gaussian of standard deviation ``sigma_l`` whose
    effective width ``2 sigma_l`` is the light's side. The area comes from
    ``emitter_areas`` (:func:`emitter_area_table`).
    """
    mi, dr = modules()
    width = dr.width(interaction.t)
    direct = mi.Color3f(dr.zeros(mi.Float, width))
    if "next_event" in parts:
        direct += parts["next_event"]
    if "emission" in parts:
        direct += parts["emission"]
    auxiliary["direct_light"] = direct
    if "light" not in parts:
        return  # _record_primary's defaults: no light sample
    direction_sample, _, active_light = parts["light"]
    attempted = parts["light_attempted"] & ~direction_sample.delta
    area = dr.gather(mi.Float, emitter_areas, dr.reinterpret_array(mi.UInt32, direction_sample.emitter), attempted)
    facing = dr.dot(direction_sample.n, direction_sample.d) < 0.0
    candidate = attempted & (area > 0.0) & (direction_sample.pdf == 0.0) & facing & \
        dr.isfinite(direction_sample.dist) & (direction_sample.dist > 0.0)
    blocker = intersect(world, interaction.spawn_ray_to(direction_sample.p), candidate)
    blocked = candidate & blocker.is_valid()
    sampled = (active_light & ~direction_sample.delta) | blocked
    distance = direction_sample.dist
    auxiliary["light_distance"] = dr.select(sampled, distance, dr.inf)
    auxiliary["occluder_distance"] = dr.select(blocked, dr.norm(direction_sample.p - blocker.p), dr.inf)
    auxiliary["light_size"] = dr.select(sampled & (area > 0.0), 0.5 * dr.sqrt(area), 0.0)


def emitter_area_table(world):
    """The surface area of each emitter's shape (0 for emitters without one), indexed by the emitter's registry
    index (``dr.reinterpret_array(mi.UInt32, emitter_pointer)``; 0, no emitter, has area 0).

    Read on the host, emitter by emitter: the kernel then gathers an area
    instead of calling ``surface_area`` through the light sample's shape
    pointer, a call Dr.Jit traces for every shape alive, which fails where
    one of them (an ``instance`` of a ``shapegroup``) has no surface area.
    At least two entries (a gather from one element compiles another kernel).
    """
    mi, dr = modules()
    areas = {}
    for emitter in world.emitters():
        shape = emitter.get_shape()
        index = int(np.ravel(np.asarray(dr.reinterpret_array(mi.UInt32, mi.EmitterPtr(emitter))))[0])
        try:
            areas[index] = float(np.ravel(np.asarray(shape.surface_area()))[0]) if shape is not None else 0.0
        except RuntimeError:  # a shape without an area: its light gets no soft-shadow width (light_size 0)
            areas[index] = 0.0
    table = np.zeros(max([1, *areas]) + 1)
    for index, area in areas.items():
        table[index] = area
    return to_device(mi.Float, table, np.float32)


def camera_axis(sensor):
    """World-space position of a loaded sensor and its unit optical axis (local +z)."""
    matrix = np.array(sensor.world_transform().matrix, dtype=np.float64).reshape(4, 4)
    forward = matrix[:3, 2] / np.linalg.norm(matrix[:3, 2])
    return tuple(float(v) for v in matrix[:3, 3]), tuple(float(v) for v in forward)


def power_heuristic(pdf_a, pdf_b):
    """Veach's power heuristic (exponent 2) weight of the strategy with density ``pdf_a``; 0 where undefined."""
    _, dr = modules()
    a2 = dr.square(pdf_a)
    b2 = dr.square(pdf_b)
    weight = a2 / (a2 + b2)
    return dr.select(dr.isfinite(weight), weight, 0.0)


def zero_nonfinite(value, valid=None):
    """``value`` with NaN or infinite lanes (and lanes not ``valid``) set to 0, and the mask of kept lanes."""
    _, dr = modules()
    finite = finite_lanes(value)
    if valid is not None:
        finite &= valid
    return dr.select(finite, value, 0.0), finite


def finite_lanes(value):
    """The lanes whose three channels are all finite."""
    _, dr = modules()
    return dr.isfinite(value.x) & dr.isfinite(value.y) & dr.isfinite(value.z)

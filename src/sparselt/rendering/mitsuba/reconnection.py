r"""The reconnection shift of gradient-domain path tracing: offset paths that rejoin the base path at its second vertex.

A base path ``x0 x1 x2 x3 ...`` of pixel ``p`` and its offset at the
neighbouring pixel ``p'`` share their random numbers up to the first hit: the
offset's camera ray goes through ``p'`` with the same film jitter and lens
sample and hits ``x1'``; its emission seen directly and its light sample at
``x1'`` (next-event estimation) replay the base's numbers. Then, instead of
replaying the BSDF sample at ``x1'`` (which sends the offset on its own way),
the offset **reconnects** to the base's second vertex ``x2``: the path
``x0' x1' x2 x3 ...`` shares everything after ``x2`` with the base, so the
light it carries is the base's, and the pair differs only by what happens at
the first vertex. Its contribution, as an estimate of ``p'``, is
``f(x0' x1' x2 ...) |J| / p(x0 x1 x2 ...)`` with the Jacobian of the vertex
change in area measure (Kettunen et al. 2015, 5.1; Lehtinen et al. 2013, 5.2)

.. math::

    |J| = \frac{|\cos\theta_2'| / \|x_1' - x_2\|^2}{|\cos\theta_2| / \|x_1 - x_2\|^2},

``theta_2`` (``theta_2'``) the angle at ``x2``'s geometric normal of the
segment from ``x1`` (``x1'``).

**Where it applies.** The base sampled a non-delta lobe at ``x1`` and at
``x2`` (diffuse or rough: Kettunen et al.'s "rough enough" vertices). The
offset's BSDF at ``x1'`` is evaluated towards ``x2`` and ``x1' -> x2`` is
tested for visibility; at ``x2`` the BSDF is evaluated again for the new
incoming direction, for its light sample (the same emitter point, whose
shadow ray does not depend on where the path came from) and for its BSDF
sample towards ``x3`` (the base's direction, divided by the base's density);
the emissions found at ``x2`` and ``x3`` get the offset's own power-heuristic
weights; everything after ``x3`` is shared. A base ray from ``x1`` that
escapes to the environment reconnects in direction (the offset keeps the
world direction: Jacobian 1; its ray must escape too). Elsewhere (a delta
lobe at ``x1`` or ``x2``, a miss at ``x1``) the offset replays the rest of
the base's numbers as well: the random-replay shift of
:mod:`sparselt.rendering.mitsuba.gradients`.

**Unbiased by two-sided multiple importance sampling.** Reconnection is not
a bijection: ``x2`` may be hidden from ``x1'``, ``x1'`` may be a mirror, and
the choice between reconnection and replay may differ from the neighbour's
point of view. Each pair is therefore weighted as Kettunen et al. (2015, 3.2)
do: a pair can be generated from ``p`` (base ``x``, offset ``T x``) or from
``p'`` (base ``T x``, offset ``x`` by the inverse shift), and its terms get the
balance-heuristic weight ``w = p_A / (p_A + p_B)`` of the side that made it,
``p_B / p_A = pdf'(x1' -> x2) |J| / pdf(x1 -> x2)`` (the ratio of the two
sides' densities of ``x2`` in area measure). Where the other side cannot
generate the pair (the shift failed: hidden, zero density, the other side
would have chosen the other shift) the base's term gets weight 1 and the
offset's 0. The gradient between ``p`` and ``p'`` is then the **sum** of the
two sides' weighted differences, and each pixel's value the mean over its
neighbours of the pair's weighted sum: both unbiased (every path's weights
sum to one over the techniques that can generate it). The parts before the
first bounce (emission seen directly, the first vertex's light sample) are
always replayed, a bijection whose offsets are each an unbiased sample of
their pixel: they are estimated as the replay shift estimates everything
(:func:`sparselt.methods.gradient_domain.gradient_estimates`), and only the
tails (everything after ``x1``) carry the pairs' weights.

References
----------
M. Kettunen, M. Manzi, M. Aittala, J. Lehtinen, F. Durand and M. Zwicker,
"Gradient-domain path tracing", ACM TOG 34(4), 2015, 3.2 and 5.1 (public
code: ``mmanzi/gradientdomain-mitsuba``, ``gpt.cpp``). J. Lehtinen, T.
Karras, S. Laine, M. Aittala, F. Durand and T. Aila, "Gradient-domain
Metropolis light transport", ACM TOG 32(4), 2013. E. Veach, "Robust Monte
Carlo methods for light transport simulation" (1997), 9.2.
"""

from __future__ import annotations

from typing import NamedTuple

from .integrand import (camera_hit, emission_found, intersect, light_contribution, light_sample, next_event,
                        power_heuristic, vertex_step)
from .runtime import modules

#: The weight of each side's tails where both sides replay (a bijection: the balance heuristic of equal densities).
REPLAY_WEIGHT = 0.5


class SplitPath(NamedTuple):
    """One lane's path cut at its first and second vertices (what a reconnection needs of it).

    ``value = before_bounce + after_first * (emission_second + tail)`` and
    ``tail = light_second + after_second * (emission_third + beyond)``.
    """

    first: object            # SurfaceInteraction3f at x1
    bsdf: object             # its BSDF
    bsdf_sample: object      # the BSDF sample at x1
    second_ray: object       # the ray x1 -> x2
    second: object           # SurfaceInteraction3f at x2
    camera_weight: object    # Color3f: the camera ray's weight
    camera_emission: object  # Color3f: emission seen directly (weighted by the camera ray)
    albedo: object           # Color3f: diffuse reflectance at x1 (0 for a miss)
    before_bounce: object    # Color3f: camera emission and the first vertex's light sample
    after_first: object      # Color3f: throughput after the BSDF sample at x1
    emission_second: object  # Color3f: emission at x2 towards x1, MIS-weighted, not multiplied by a throughput
    second_vertex: object    # SecondVertex, or None for a layout of one vertex
    tail: object             # Color3f: everything after x2, with throughput 1 at x2
    reconnectable: object    # Bool: non-delta samples at x1 and x2 (x3 found or not), or at x1 into the sky
    escaped: object          # Bool: the ray from x1 found no surface (x2 is a direction: the environment's)
    value: object            # Color3f: the path's contribution


class SecondVertex(NamedTuple):
    """What happens at ``x2``: the parts of :attr:`SplitPath.tail` that depend on the direction the path arrives
    from, and those that do not."""

    bsdf: object             # the BSDF at x2
    light: object            # its light sample (direction sample, emitter weight, lanes), or None
    bsdf_sample: object      # the BSDF sample at x2
    light_value: object      # Color3f: the light sample's contribution (throughput 1 at x2)
    after_second: object     # Color3f: the BSDF sample's weight f cos / pdf at x2
    emission_raw: object     # Color3f: emission at x3 towards x2, unweighted
    emission_light_pdf: object  # Float: the density of next-event estimation at x2 of that emission's point
    emission_weight: object  # Float: its power-heuristic weight (1 without next-event estimation at x2)
    beyond: object           # Color3f: everything after x3, with throughput 1 at x3


def split_path(scene, layout, samples, tail_active=True):
    """The path estimator of :func:`~sparselt.rendering.mitsuba.integrand.path_contribution`, cut at ``x1``, ``x2``.

    The same estimator (Mitsuba's ``path`` with MIS, no Russian roulette),
    its value assembled from the parts that an offset path reconnected at
    ``x2`` replaces or evaluates again. Lanes not ``tail_active`` stop after
    their first vertex (their ``after_first`` part is 0): a masked lane costs
    no ray beyond it.

    Returns
    -------
    SplitPath
    """
    mi, dr = modules()
    context = mi.BSDFContext()
    world = scene.scene
    ray, camera_weight, first = camera_hit(scene, layout, samples)
    valid = first.is_valid()
    lanes = dr.width(valid)
    zero = dr.zeros(mi.Color3f, lanes)
    camera_emission = camera_weight * first.emitter(world).eval(first) if layout.count_camera_emission else zero
    before_bounce = mi.Color3f(camera_emission)
    bsdf = first.bsdf(ray)
    albedo = dr.select(valid, mi.Color3f(bsdf.eval_diffuse_reflectance(first, valid)), 0.0)
    if not layout.vertices:
        none = dr.zeros(mi.Bool, lanes)
        return SplitPath(first, bsdf, None, None, None, camera_weight, camera_emission, albedo, before_bounce, zero,
                         zero, None, zero, none, none, before_bounce)
    plan = layout.vertices[0]
    if plan.next_event:
        before_bounce += next_event(world, context, bsdf, first, samples, 1, camera_weight, valid)
    direction = mi.Point2f(samples["bsdf1_u"], samples["bsdf1_v"])
    bsdf_sample, bsdf_weight = bsdf.sample(context, first, samples["lobe1"], direction, valid)
    alive = valid & tail_active
    after_first = dr.select(alive, camera_weight * bsdf_weight, 0.0)
    alive &= dr.max(after_first) > 0.0
    second_ray = first.spawn_ray(first.to_world(bsdf_sample.wo))
    second = intersect(world, second_ray, alive)
    delta = mi.has_flag(bsdf_sample.sampled_type, mi.BSDFFlags.Delta)
    emission_second = zero
    if plan.count_emission_hit:
        emission_second = dr.select(alive, emission_found(world, plan, first, second, bsdf_sample.pdf, delta, alive),
                                    0.0)
    escaped = alive & ~delta & ~second.is_valid()
    reconnectable = alive & ~delta & second.is_valid()
    vertex = None
    tail = zero
    if len(layout.vertices) > 1:
        vertex, third_delta = _second_vertex(world, context, layout, samples, second, second_ray, alive)
        tail = vertex.light_value + vertex.after_second * (vertex.emission_raw * vertex.emission_weight
                                                         + vertex.beyond)
        reconnectable &= ~third_delta
    value = before_bounce + after_first * (emission_second + tail)
    return SplitPath(first, bsdf, bsdf_sample, second_ray, second, camera_weight, camera_emission, albedo,
                     before_bounce, after_first, emission_second, vertex, tail, reconnectable | escaped, escaped,
                     value)


def _second_vertex(world, context, layout, samples, second, second_ray, alive):
    """:class:`SecondVertex` of the lanes ``alive`` at ``x2``, and whether the BSDF sample there was a delta."""
    mi, dr = modules()
    plan = layout.vertices[1]
    lanes = dr.width(alive)
    active = alive & second.is_valid()
    bsdf = second.bsdf(second_ray)
    light, light_value = None, dr.zeros(mi.Color3f, lanes)
    if plan.next_event:
        light = light_sample(world, bsdf, second, samples, 2, active)
        light_value = light_contribution(context, bsdf, second, light, dr.full(mi.Color3f, 1.0, lanes))
    direction = mi.Point2f(samples["bsdf2_u"], samples["bsdf2_v"])
    bsdf_sample, bsdf_weight = bsdf.sample(context, second, samples["lobe2"], direction, active)
    after_second = dr.select(active, bsdf_weight, 0.0)
    live = active & (dr.max(after_second) > 0.0)
    ray = second.spawn_ray(second.to_world(bsdf_sample.wo))
    third = intersect(world, ray, live)
    delta = mi.has_flag(bsdf_sample.sampled_type, mi.BSDFFlags.Delta)
    emission_raw, light_pdf, weight = dr.zeros(mi.Color3f, lanes), dr.zeros(mi.Float, lanes), dr.ones(mi.Float, lanes)
    if plan.count_emission_hit:
        emitter_sample = mi.DirectionSample3f(world, si=third, ref=second)
        emission_raw = dr.select(live, emitter_sample.emitter.eval(third, live), 0.0)
        if plan.next_event:
            light_pdf = world.pdf_emitter_direction(second, emitter_sample, live & ~delta)
            weight = power_heuristic(bsdf_sample.pdf, light_pdf)
    beyond, throughput = dr.zeros(mi.Color3f, lanes), dr.full(mi.Color3f, 1.0, lanes)
    interaction, live_beyond = third, live
    for index, vertex_plan in enumerate(layout.vertices[2:], start=3):
        beyond, interaction, ray, throughput, live_beyond, _ = vertex_step(
            world, context, vertex_plan, index, samples, interaction, ray, throughput, live_beyond, beyond)
    return SecondVertex(bsdf, light, bsdf_sample, light_value, after_second, emission_raw, light_pdf, weight,
                        beyond), delta & live


class ShiftedPair(NamedTuple):
    """One base path and one offset: values and the side's MIS-weighted tails (see the module's docstring)."""

    offset: SplitPath        # the offset's own trace (its replay, where it replays)
    offset_value: object     # Color3f: the offset's contribution (its replayed part and its tail; 0 where it failed)
    weighted_base: object    # Color3f: the base's tail (after x1) times this side's weight
    weighted_offset: object  # Color3f: the offset's tail times this side's weight
    reconnected: object      # Bool: the offset reconnected to the base's x2 (and x2 was visible from x1')


def shifted_pair(scene, layout, base, offset_samples, inside):
    """The offset of ``base`` whose PSS vector is ``offset_samples``: reconnected where ``base`` allows, replayed
    elsewhere, with both sides' weights.

    Parameters
    ----------
    scene : MitsubaScene
    layout : PathLayout
    base : SplitPath
        :func:`split_path` of the base lanes.
    offset_samples : dict
        The base's PSS vectors with the film position moved to the neighbour.
    inside : mi.Bool
        The neighbour is inside the film (elsewhere every output is 0).

    Returns
    -------
    ShiftedPair
    """
    mi, dr = modules()
    context = mi.BSDFContext()
    world = scene.scene
    lanes = dr.width(inside)
    reconnect = base.reconnectable & inside
    offset = split_path(scene, layout, offset_samples, tail_active=inside & ~reconnect)
    zero = dr.zeros(mi.Color3f, lanes)
    if base.second is None:  # no vertex: only the replayed parts
        return ShiftedPair(offset, dr.select(inside, offset.value, 0.0), zero, zero, dr.zeros(mi.Bool, lanes))
    first = offset.first
    attempt = reconnect & first.is_valid()
    escaped = base.escaped
    to_second = base.second.p - first.p
    squared_distance = dr.squared_norm(to_second)
    # Into the sky the shared vertex is a direction: the offset keeps it (solid angle measure, Jacobian 1).
    direction = dr.select(escaped, base.second_ray.d, to_second * dr.rsqrt(squared_distance))
    bsdf_value, bsdf_pdf = offset.bsdf.eval_pdf(context, first, first.to_local(direction), attempt)
    normal = base.second.n
    cosine_base = dr.dot(normal, -base.second_ray.d)
    cosine_offset = dr.dot(normal, -direction)
    arriving = base.second.to_local(-direction)
    same_side = escaped | ((cosine_base * cosine_offset > 0.0)
                           & (mi.Frame3f.cos_theta(arriving) * mi.Frame3f.cos_theta(base.second.wi) > 0.0))
    attempt &= same_side & (bsdf_pdf > 0.0)
    attempt &= ~world.ray_test(first.spawn_ray_to(base.second.p), attempt & ~escaped)
    attempt &= ~world.ray_test(first.spawn_ray(direction), attempt & escaped)
    jacobian = dr.select(escaped, 1.0,
                         (dr.abs(cosine_offset) / squared_distance) / (dr.abs(cosine_base) / dr.square(base.second.t)))
    # p_B / p_A: the other side's density of the shared vertices over this side's, in area (or solid angle) measure.
    density_ratio = bsdf_pdf * jacobian / base.bsdf_sample.pdf
    after_first = dr.select(attempt, offset.camera_weight * bsdf_value * (jacobian / base.bsdf_sample.pdf), 0.0)
    moved = mi.SurfaceInteraction3f(base.second)
    moved.wi = dr.select(escaped, base.second.wi, arriving)
    emission_second = zero
    plan = layout.vertices[0]
    if plan.count_emission_hit:
        emission_second = dr.select(attempt, emission_found(world, plan, first, moved, bsdf_pdf, mi.Bool(False),
                                                            attempt), 0.0)
    # The tails in two parts with their own weights: what ends at x2 (its emission, its light sample), whose
    # density ratio is that of x2 alone, and what continues through x3, whose ratio has x3's densities too.
    vertex = base.second_vertex
    base_near = base.after_first * (base.emission_second + (vertex.light_value if vertex is not None else zero))
    base_far = base.after_first * (base.tail - vertex.light_value) if vertex is not None else zero
    near = after_first * emission_second
    far = zero
    far_ratio = density_ratio
    if vertex is not None:  # x2's BSDF evaluated again for the new incoming direction; x3 and beyond shared
        next_plan = layout.vertices[1]
        if vertex.light is not None:
            direction_sample, emitter_weight, lit = vertex.light
            near += after_first * light_contribution(context, vertex.bsdf, moved,
                                                     (direction_sample, emitter_weight, lit & attempt),
                                                     dr.full(mi.Color3f, 1.0, lanes))
        sampled = vertex.bsdf_sample
        value_second, pdf_second = vertex.bsdf.eval_pdf(context, moved, sampled.wo, attempt)
        continued = attempt & (dr.max(vertex.after_second) > 0.0)
        after_second = dr.select(continued, value_second / sampled.pdf, 0.0)
        emission_weight = vertex.emission_weight
        if next_plan.count_emission_hit and next_plan.next_event:
            emission_weight = power_heuristic(pdf_second, vertex.emission_light_pdf)
        far = after_first * after_second * (vertex.emission_raw * emission_weight + vertex.beyond)
        far_ratio = density_ratio * dr.select(continued, pdf_second / sampled.pdf, 1.0)
    replayed_tail = offset.after_first * (offset.emission_second + offset.tail)
    offset_tail = dr.select(reconnect, dr.select(attempt, near + far, 0.0), replayed_tail)
    # Each side's weight: the balance heuristic where the other side can make the pair, else 1 (base) and 0.
    replay_base = dr.select(offset.reconnectable, 1.0, REPLAY_WEIGHT)
    replay_offset = dr.select(offset.reconnectable, 0.0, REPLAY_WEIGHT)
    near_balance = dr.select(attempt, 1.0 / (1.0 + density_ratio), 1.0)
    far_balance = dr.select(attempt, 1.0 / (1.0 + far_ratio), 1.0)
    weighted_base = dr.select(reconnect, near_balance * base_near + far_balance * base_far,
                              replay_base * (base_near + base_far))
    weighted_offset = dr.select(reconnect, dr.select(attempt, near_balance * near + far_balance * far, 0.0),
                                replay_offset * replayed_tail)
    offset_value = dr.select(inside, offset.before_bounce + offset_tail, 0.0)
    weighted_base = dr.select(inside, weighted_base, 0.0)
    weighted_offset = dr.select(inside, weighted_offset, 0.0)
    return ShiftedPair(offset, offset_value, weighted_base, weighted_offset, attempt)

"""The render loop, compiled: every depth of a pass's rays in one ``nogil`` call.

:func:`trace_paths` takes a pass's camera rays and does, depth after depth and without
returning to Python, what :class:`raytrace.integrator.WhittedIntegrator`'s loop describes
(Whitted 1980; seed 003's trace/shade pseudocode): the closest hits (analytic shapes in
float64, Embree's packets, the float64 re-solve of mesh hits and the re-trace past float32
artefacts), the background of the misses, the surfaces, each light's term and its shadow rays
(occlusion packets, or the walk through transparent surfaces), the hits' own terms and their
reflected, refracted and see-through children, the next depth. It calls the same per-batch
kernels as that loop, in the same order and on the same rows, so each sample adds up the same
numbers in the same order: the images are bit-identical to it (tests/test_loop.py), for any
number of threads. Python hands each thread its passes (:meth:`WhittedIntegrator._run`) and
takes no part between depths; the GIL is held only to start a pass and to average its pixels.

A scene compiles only what it uses: the kernels' feature arguments (``meshes``, ``children``,
textures in the scene record) are None where a scene lacks the feature, as in the Python
loop, and numba prunes the branches that test them before typing.

Its first compile is kept small (docs/performance.md, "The compiled loop"): the steps called
from one place are inlined in numba's IR (``jit.inline``), every function only compiled code
calls has no CPython or C entry point and one set of numba options (``jit.INNER``, so numpy's
functions compile once for all of them), the overloads that pick a feature's code are not
also inlined (numba compiles an overload's implementation in full either way), and arrays
are made with ``np.empty`` and filled in place (``np.zeros``, ``np.full``, ``np.ones``,
``np.arange`` and ``np.count_nonzero`` are each a compile of their own).

Every record it takes is built once per render by :mod:`raytrace.integrator`
(:class:`raytrace.kernels.records.Tracer`, :class:`raytrace.kernels.records.LightTable`,
:class:`raytrace.kernels.records.PassSettings`); its counters are the ``--stats`` of the
pass (:data:`COUNTERS`, :data:`SECONDS`). Timing uses the C library's ``clock_gettime`` by
address, like Embree's calls (:func:`raytrace.kernels.embree.call4`).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload
from numba.np.unsafe.ndarray import to_fixed_tuple

from . import accel as ak
from . import aov as aovk
from . import camera as ck
from . import core
from . import embree as ek
from . import rays as rk
from . import shading as sk
from .jit import INNER, helper, inline, kernel
from .kinds import NO_SHAPE, NONE, PRUNED, REFLECTION, REFRACTION, SEE_THROUGH
from .records import (
    EMITTER_FIELDS,
    Children,
    EmbreeHits,
    EmbreeRays,
    Emitter,
    Hits,
    Local,
    Query,
    Rays,
    Redo,
    SampleSums,
    Scene,
    ShadowQuery,
    Shadows,
    ShadowWalk,
    Spawned,
    Surface,
)

#: Most second passes of a query over the rays whose hits were float32 artefacts.
MAX_RETRACES = 4
#: Most surfaces a transparent shadow ray passes through before it counts as blocked.
MAX_SHADOW_CROSSINGS = 64
#: The counters a pass adds to, by column of its int64 ``counters`` array: rays of each kind
#: (kinds.CAMERA … SEE_THROUGH: columns 0–3), then these.
SHADOW_RAYS, PRUNED_DEPTH, PRUNED_WEIGHT, TIR = 4, 5, 6, 7
COUNTERS = 8
#: Kinds of the children, in the order of their columns (reflected, refracted, see-through).
CHILD_KINDS = np.array([REFLECTION, REFRACTION, SEE_THROUGH], np.int8)
#: Its float64 ``seconds``: time spent tracing (Embree and the analytic shapes), and shading.
TRACE_SECONDS, SHADE_SECONDS = 0, 1
SECONDS = 2
#: Where a ray has no bound (an empty column).
NO_TMAX = np.empty(0)


@intrinsic
def _clock(typingctx, function, clock_id, timespec):
    """Call ``clock_gettime(clock_id, timespec)`` at address ``function``."""
    sig = types.int32(function, clock_id, timespec)

    def codegen(context, builder, signature, args):
        i32, pointer = ir.IntType(32), ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(i32, [i32, pointer])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(f, [builder.trunc(args[1], i32), builder.inttoptr(args[2], pointer)])

    return sig, codegen


@helper
def now(settings, timespec):
    """Seconds of the monotonic clock (0 where no ``clock_gettime`` was found)."""
    if settings.clock == 0:
        return 0.0
    _clock(settings.clock, settings.clock_id, ek.address(timespec))
    return timespec[0] + 1e-9 * timespec[1]


@helper
def emitter_at(table, e):
    """Emitter ``e`` of ``table.rows`` (a :class:`raytrace.kernels.records.LightTable`) as
    the light pass takes it (:class:`raytrace.kernels.records.Emitter`: its row is the record's
    fields in order)."""
    return Emitter(*to_fixed_tuple(table.rows[e], EMITTER_FIELDS))


# -- queries ---------------------------------------------------------------------------------
def closest_triangles(tracer, query, hits, packets):
    """Embree's closest hits of ``query``'s rays into ``hits``: :func:`_closest_triangles`,
    nothing in a scene without meshes (``tracer.embree`` None: no Embree code compiled)."""


@overload(closest_triangles, jit_options=INNER)
def _closest_triangles_by_type(tracer, query, hits, packets):
    if field_is_none(tracer, "embree"):
        return lambda tracer, query, hits, packets: None
    return _closest_triangles


def _closest_triangles(tracer, query, hits, packets):
    """Embree's closest hits of ``query``'s rays written into ``hits`` where a triangle comes
    before the analytic hit (and ``tmax``), with the float64 re-solve and up to
    :data:`MAX_RETRACES` second passes past float32 artefacts
    (``raytrace.accel.Accelerator._closest_triangles``, the same steps); ``packets``: the
    first pass's COHERENT packets (empty: plain ones)."""
    n = query.origin.shape[0]
    rays = EmbreeRays(np.empty((n, 3), np.float32), np.empty((n, 3), np.float32),
                      np.empty(n, np.float32))
    ak.embree_rays(query, hits.t, rays)
    redo = Redo(np.empty(n, np.int64), np.empty(n))
    traced = Redo(np.empty(0, np.int64), np.empty(0))
    for _ in range(MAX_RETRACES + 1):
        m = rays.far.shape[0]
        out = EmbreeHits(np.empty(m, np.int32), np.empty(m, np.int32), np.empty(m, np.float32),
                         np.empty(m, np.float32))
        ek.closest_hits(tracer.embree, rays, packets, out)
        packets = packets[:0]  # plain: the rays traced again are a scattered few
        k = ak.refine_hits(out, traced, tracer.scene.triangles, query, hits, redo)
        if k == 0:
            return
        kept = Redo(np.empty(k, np.int64), np.empty(k))
        again = EmbreeRays(np.empty((k, 3), np.float32), np.empty((k, 3), np.float32),
                           np.empty(k, np.float32))
        k = ak.retrace_rays(Redo(redo.rows[:k], redo.adv[:k]), query, hits.t,
                            again, kept)
        if k == 0:
            return
        traced = Redo(kept.rows[:k], kept.adv[:k])
        rays = EmbreeRays(again.origin[:k], again.direction[:k], again.far[:k])


@inline
def intersect(tracer, origin, direction, origin_shape, tmax, packets):
    """Closest hit of each ray with ``0 < t < tmax`` (``tmax`` empty: unbounded), analytic
    shapes first, then Embree (``raytrace.accel.Accelerator.intersect``; ``packets``: the
    COHERENT packets of camera rays; empty: plain ones)."""
    n = origin.shape[0]
    t, shape = np.empty(n), np.empty(n, np.int64)
    has_tmax = tmax.shape[0] > 0
    if tracer.shapes.kind.shape[0] == 0:
        t[:] = np.inf
        shape[:] = NO_SHAPE
    else:
        ak.closest_analytic(origin, direction, origin_shape, tmax, has_tmax,
                            tracer.shapes, t, shape)
    triangle = np.empty(n, np.int64)
    triangle[:] = -1
    uv = np.empty((n, 2))
    uv[:] = 0.0
    hits = Hits(t, shape, triangle, uv)
    if n:
        closest_triangles(tracer, Query(origin, direction, tmax, has_tmax), hits, packets)
    return hits


def depth_hits(tracer, rays, depth, packets):
    """The closest hits of a batch at ``depth``: the camera rays' through their COHERENT
    packets where the pass has them (:func:`_packet_hits`; ``packets`` None: none), else in
    plain packets."""


@overload(depth_hits, jit_options=INNER)
def _depth_hits_by_type(tracer, rays, depth, packets):
    if isinstance(packets, types.NoneType):
        return lambda tracer, rays, depth, packets: intersect(
            tracer, rays.origin, rays.direction, rays.origin_shape, NO_TMAX,
            np.empty(0, np.int64))
    return _packet_hits


def _packet_hits(tracer, rays, depth, packets):
    """:func:`depth_hits` with the camera rays' packets (a
    :class:`raytrace.kernels.records.CameraPackets`): at depth 0, every slot of the packets
    traced (``WhittedIntegrator.trace``, the same steps), the hits of the pass's own rays
    kept, in the batch's order (``kernels.camera.own_hits``)."""
    n, m = rays.origin.shape[0], packets.sample.shape[0]
    own = 0
    for i in range(m):
        own += packets.sample[i] >= 0
    if depth > 0 or own != n:  # (a batch that is not the pass's camera rays)
        return intersect(tracer, rays.origin, rays.direction, rays.origin_shape, NO_TMAX,
                         packets.bounds[:0])
    shape = np.empty(m, np.int64)
    shape[:] = NO_SHAPE
    every = intersect(tracer, np.zeros((m, 3)), packets.direction, shape, NO_TMAX,
                      packets.bounds)
    if m == n:  # every slot the batch's own, in its order
        return every
    hits = Hits(np.empty(n), np.empty(n, np.int64), np.empty(n, np.int64), np.empty((n, 2)))
    ck.own_hits(packets, every, hits)
    return hits


@helper
def occluded(tracer, origin, direction, origin_shape, tmax, coherent):
    """True where something lies in ``(0, tmax)`` (``raytrace.accel.Accelerator.occluded``:
    the analytic shapes' any-hit pass, Embree's occlusion packets, and closest-hit queries
    for the blocked rays that start on a triangle)."""
    n = origin.shape[0]
    blocked = np.empty(n, np.bool_)
    m = n if tracer.meshes else 0
    idx = np.empty(m, np.int64)
    rays = EmbreeRays(np.empty((m, 3), np.float32), np.empty((m, 3), np.float32),
                      np.empty(m, np.float32))
    k = ak.shadow_prepass(ShadowQuery(origin, direction, origin_shape, tmax), tracer.shapes,
                          tracer.meshes, blocked, idx, rays)
    if k:
        embree_occlusion(tracer, ShadowQuery(origin, direction, origin_shape, tmax), coherent,
                         blocked, idx[:k], EmbreeRays(rays.origin[:k], rays.direction[:k],
                                                      rays.far[:k]))
    return blocked


def embree_occlusion(tracer, query, coherent, blocked, idx, rays):
    """``blocked[idx[j]]`` for the rays ``rays`` the analytic shapes left to Embree (ray
    ``idx[j]`` of ``query``): :func:`_embree_occlusion`, compiled only with meshes."""


@overload(embree_occlusion, jit_options=INNER)
def _embree_occlusion_by_type(tracer, query, coherent, blocked, idx, rays):
    if field_is_none(tracer, "embree"):
        return lambda tracer, query, coherent, blocked, idx, rays: None
    return _embree_occlusion


def _embree_occlusion(tracer, query, coherent, blocked, idx, rays):
    """Embree's occlusion packets, then closest-hit queries for the blocked rays that start
    on a triangle, whose blocker may be a float32 artefact (``Accelerator.occluded``)."""
    k = idx.shape[0]
    origin, direction, tmax = query.origin, query.direction, query.tmax
    result = np.empty(k, np.int32)
    ek.any_hits(tracer.embree, rays, coherent, result)
    recheck = np.empty(k, np.int64)
    j = ak.occlusion(idx, result, query.origin_shape, blocked, recheck)
    if j:
        o, d, lim = np.empty((j, 3)), np.empty((j, 3)), np.empty(j)
        for r in range(j):
            i = recheck[r]
            for c in range(3):
                o[r, c], d[r, c] = origin[i, c], direction[i, c]
            lim[r] = tmax[i]
        t, shape = np.empty(j), np.empty(j, np.int64)
        t[:] = np.inf
        shape[:] = NO_SHAPE
        closest_triangles(tracer, Query(o, d, lim, True),
                          Hits(t, shape, np.empty(j, np.int64), np.empty((j, 2))),
                          np.empty(0, np.int64))
        for r in range(j):
            blocked[recheck[r]] = math.isfinite(t[r])


@helper
def surfaces(tracer, hits, origin, direction):
    """Points, normals and materials at the hits (every row a hit): ``hit_surfaces``."""
    n = hits.t.shape[0]
    surface = Surface(np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)),
                      np.empty(n, np.int64), np.empty(n), hits.shape, hits.triangle, hits.uv)
    ak.hit_surfaces(hits, origin, direction, tracer.shapes, tracer.scene.triangles,
                    tracer.scene.reliefs, surface)
    return surface


# -- one depth -------------------------------------------------------------------------------
def shadow(tracer, settings, shadows, k, coherent, tally):
    """The shadow rays' answer: :func:`_opaque_shadow` or, where something is transparent
    (``tracer.transparent`` True), :func:`_transparent_shadow`; only that one is compiled."""


@overload(shadow, jit_options=INNER)
def _shadow_by_type(tracer, settings, shadows, k, coherent, tally):
    return _opaque_shadow if field_is_none(tracer, "transparent") else _transparent_shadow


def _opaque_shadow(tracer, settings, shadows, k, coherent, tally):
    """The occlusion flags of the first ``k`` rays of ``shadows``: (rows, no factors, flags)."""
    counters, seconds, timespec = tally.counters, tally.seconds, tally.timespec
    counters[SHADOW_RAYS] += k
    t0 = now(settings, timespec)
    blocked = occluded(tracer, shadows.origin[:k], shadows.direction[:k], shadows.shape[:k],
                       shadows.tmax[:k], coherent)
    seconds[TRACE_SECONDS] += now(settings, timespec) - t0
    return shadows.rows[:k], np.empty((0, 3)), blocked


def _transparent_shadow(tracer, settings, shadows, k, coherent, tally):
    """The shadow factors of the first ``k`` rays of ``shadows`` (a
    :class:`raytrace.kernels.records.Shadows`), (k, 3), in a scene where something is
    transparent: the product of ``t·kt + (1 − t)`` over the surfaces each ray walks through
    to its light (seed 003; ``WhittedIntegrator.shadow``), 0 past
    :data:`MAX_SHADOW_CROSSINGS`. Returns the rows, the factors and no occlusion flags. Its
    closest-hit queries use plain packets, so ``coherent`` (the opaque form's) is not read."""
    counters, seconds, timespec = tally.counters, tally.seconds, tally.timespec
    rows, origin, direction = shadows.rows[:k], shadows.origin[:k], shadows.direction[:k]
    tmax, shape = shadows.tmax[:k], shadows.shape[:k]
    counters[SHADOW_RAYS] += k
    t0 = now(settings, timespec)
    factor = np.empty((k, 3))
    factor[:] = 1.0
    live = np.empty(k, np.int64)
    for r in range(k):
        live[r] = r
    walked = False
    for _ in range(MAX_SHADOW_CROSSINGS):
        hits = intersect(tracer, origin, direction, shape, tmax, np.empty(0, np.int64))
        t, hit_shape, triangle, uv, origin, direction, tmax, live = sk.crossing_rays(
            hits, origin, direction, tmax, live)
        if live.shape[0] == 0:
            walked = True
            break
        s2 = surfaces(tracer, Hits(t, hit_shape, triangle, uv), origin, direction)
        origin, direction, shape, tmax, live = sk.cross_surfaces(
            factor, live, s2, ShadowWalk(direction, t, tmax), tracer.scene)
        if live.shape[0] == 0:
            walked = True
            break
        counters[SHADOW_RAYS] += live.shape[0]
    if not walked:
        for r in range(live.shape[0]):
            factor[live[r], 0] = factor[live[r], 1] = factor[live[r], 2] = 0.0
    seconds[TRACE_SECONDS] += now(settings, timespec) - t0
    return rows, factor, np.empty(0, np.bool_)


def direct_lighting(tracer, lights, settings, rays, depth, pass_io, surf, tally):
    """Σ_l S_l·f_l·I_l·[…] at every hit: :func:`_direct_lighting`, or no rows in a scene
    without lights or lit materials (``tracer.lit`` None: no light pass compiled)."""


@overload(direct_lighting, jit_options=INNER)
def _direct_lighting_by_type(tracer, lights, settings, rays, depth, pass_io, surf, tally):
    if field_is_none(tracer, "lit"):
        return lambda tracer, lights, settings, rays, depth, pass_io, surf, tally: \
            np.empty((0, 3))
    return _direct_lighting


def hit_keys(keys, rays, depth):
    """Each hit's jitter key: its sample's (``keys``) below the camera rays hashed with its
    ray (``core.path_key1``: each path of a sample its own points); no rows where no light
    is jittered (``keys`` None: no key code compiled)."""


@overload(hit_keys, jit_options=INNER)
def _hit_keys_by_type(keys, rays, depth):
    if isinstance(keys, types.NoneType):
        return lambda keys, rays, depth: np.empty(0, np.int64)
    return _hit_keys


def _hit_keys(keys, rays, depth):
    n = rays.origin.shape[0]
    key = np.empty(n, np.int64)
    for i in range(n):
        key[i] = keys[rays.sample[i]]
    if depth == 0:
        return key
    path = np.empty(n, np.int64)
    core.path_keys(key, rays.origin.view(np.uint64), rays.direction.view(np.uint64), path)
    return path


def _direct_lighting(tracer, lights, settings, rays, depth, pass_io, surf, tally):
    """Σ_l S_l · f_l · I_l · [kd·max(N·L, 0) + ks·spec] at every hit, (n, 3): per emitter,
    the light pass and its shadow rays (``WhittedIntegrator.direct_lighting``). ``pass_io``:
    the pass's :class:`raytrace.kernels.records.PassIO` (its ``keys``: each pass sample's
    jitter key, None: no jittered light; its ``stop`` flag, read before each emitter, since
    an area light's hundreds of emitters may take seconds); ``tally``: the pass's
    :class:`raytrace.kernels.records.Tally`."""
    n = rays.origin.shape[0]
    out = np.empty((n, 3))
    out[:] = 0.0
    term = np.empty((n, 3))
    shadows = Shadows(np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3)), np.empty(n),
                      np.empty(n, np.int64))
    key = hit_keys(pass_io.keys, rays, depth)
    scene = tracer.scene
    for e in range(lights.rows.shape[0]):
        if pass_io.stop[0] != 0:  # the pass ends: what it adds no longer counts
            break
        em = emitter_at(lights, e)
        words = np.empty(0, np.int64)
        if em.stream >= 0 and key.shape[0]:
            words = np.empty(n, np.int64)
            core.light_words(key, np.int64(em.stream), np.int64(depth), words)
        fast = lights.fast[lights.fast_first[e]:lights.fast_first[e + 1]]
        tables = Scene(scene.origin, scene.materials, scene.triangles, fast, scene.texcoords,
                       scene.media, scene.mips, scene.reliefs,
                       scene.spread)  # every field: numba has no defaults
        k = sk.light_pass(rays, surf, tables, em, words, light_depth(tracer.shaded, depth),
                          term, shadows)
        if k:  # the camera rays' hits send coherent shadow rays to a point
            rows, factor, blocked = shadow(tracer, settings, shadows, k,
                                           depth == 0 and em.stream < 0, tally)
            if factor.shape[0]:
                sk.add_light(out, rows, term, factor, lights.color[e])
            else:
                sk.add_unblocked(out, rows, term, blocked, lights.color[e])
    return out


@inline
def spawn(rays, surf, children):
    """The children whose status is KEEP, reflected then refracted then see-through, each in
    hit order (``WhittedIntegrator._spawn``): a new batch of rays."""
    per_kind = sk.count_keep(children.status)
    first = np.empty(3, np.int64)
    first[0] = 0
    first[1] = per_kind[0]
    first[2] = per_kind[0] + per_kind[1]
    k = per_kind[0] + per_kind[1] + per_kind[2]
    out = Spawned(np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3)), np.empty(k, np.int64),
                  np.empty(k, np.int64), np.empty(k, np.int8), np.empty(k, np.int64))
    sk.spawn_children(children, rays, surf, first, CHILD_KINDS, out)
    return Rays(out.origin, out.direction, out.sample, out.weight, out.shape, out.kind)


@inline
def trace_depth(tracer, lights, settings, rays, depth, pass_io, tally):
    """One depth of a batch: intersect, add the background of the misses and the local terms
    of the hits into ``pass_io``'s sums, return the next depth's rays
    (``WhittedIntegrator.trace`` and ``shade``). ``pass_io``: a
    :class:`raytrace.kernels.records.PassIO`; ``tally``: a
    :class:`raytrace.kernels.records.Tally`."""
    samples, aov = pass_io.samples, pass_io.aov
    counters, seconds, timespec = tally.counters, tally.seconds, tally.timespec
    n = rays.origin.shape[0]
    rk.count_kinds(rays.kind, counters)
    t0 = now(settings, timespec)
    hits = depth_hits(tracer, rays, depth, pass_io.packets)
    seconds[TRACE_SECONDS] += now(settings, timespec) - t0
    found, missed = np.empty(n, np.int64), np.empty(n, np.int64)
    k = rk.split_hits(hits.t, found, missed)
    if n - k and settings.any_background:
        sk.accumulate(samples, rays.sample, rays.weight, settings.background,
                      missed[:n - k])
    if k == 0:
        return no_rays()
    t1 = now(settings, timespec)
    trace_before = seconds[TRACE_SECONDS]
    if k < n:  # compaction: only the hits go on
        taken = Rays(np.empty((k, 3)), np.empty((k, 3)), np.empty(k, np.int64),
                     np.empty((k, 3)), np.empty(k, np.int64), np.empty(k, np.int8))
        kept = Hits(np.empty(k), np.empty(k, np.int64), np.empty(k, np.int64),
                    np.empty((k, 2)))
        rk.take_hits(found[:k], rays, hits, taken, kept)
        rays, hits = taken, kept
    surf = surfaces(tracer, hits, rays.origin, rays.direction)
    if depth == 0:
        first_hit_aovs(tracer, rays, hits, surf, aov)
    lit = direct_lighting(tracer, lights, settings, rays, depth, pass_io, surf, tally)
    m = rays.origin.shape[0]
    children = room_for_children(tracer.children, m)
    sk.hit_terms(rays, surf, tracer.scene, Local(settings.ambient, lit), settings.min_weight,
                 SampleSums(samples, rays.sample), children)
    result = next_depth(children, rays, surf, depth, settings, counters)
    seconds[SHADE_SECONDS] += now(settings, timespec) - t1 - (
        seconds[TRACE_SECONDS] - trace_before)
    return result


def first_hit_aovs(tracer, rays, hits, surf, aov):
    """The AOVs of the camera rays' hits into ``aov``: nothing (and no AOV code compiled)
    where ``aov`` is None."""


@overload(first_hit_aovs, jit_options=INNER)
def _first_hit_aovs_by_type(tracer, rays, hits, surf, aov):
    if isinstance(aov, types.NoneType):
        return lambda tracer, rays, hits, surf, aov: None
    return lambda tracer, rays, hits, surf, aov: aovk.aov_hits(
        rays, hits.t, surf, tracer.scene, tracer.objects, tracer.aov_layout, aov)


def field_is_none(record, name: str) -> bool:
    """Whether field ``name`` of a named-tuple type (as numba types a record) is None: what
    the overloads above choose their code by."""
    return isinstance(record.types[record.instance_class._fields.index(name)], types.NoneType)


def no_rays():
    """An empty batch."""
    return Rays(np.empty((0, 3)), np.empty((0, 3)), np.empty(0, np.int64), np.empty((0, 3)),
                np.empty(0, np.int64), np.empty(0, np.int8))


@overload(no_rays, jit_options=INNER)
def _no_rays():
    return no_rays


# -- what a scene leaves out, chosen by type (numba.extending.overload) -----------------------
# A feature field of the Tracer record is None where the scene lacks the feature; each helper
# below has one implementation per type, so only the one the scene needs is compiled (as the
# Python loop passes None to the same kernels).
def light_depth(shaded, depth):
    """The light pass's ``depth``: None in a scene without triangles and image textures (its
    mesh and texture code is then not compiled), else the rays' depth."""
    return None if shaded is None else depth


@overload(light_depth, jit_options=INNER)
def _light_depth(shaded, depth):
    if isinstance(shaded, types.NoneType):
        return lambda shaded, depth: None
    return lambda shaded, depth: depth


def room_for_children(children, m):
    """Room for the children of ``m`` hits (a :class:`raytrace.kernels.records.Children`),
    or None in a scene where nothing reflects or transmits."""
    if children is None:
        return None
    return Children(np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3)),
                    np.empty((m, 3)), np.empty((m, 3), np.int8), np.empty(m, np.bool_))


@overload(room_for_children, jit_options=INNER)
def _room_for_children(children, m):
    if isinstance(children, types.NoneType):
        return lambda children, m: None
    return lambda children, m: Children(
        np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3)),
        np.empty((m, 3)), np.empty((m, 3), np.int8), np.empty(m, np.bool_))


def next_depth(children, rays, surf, depth, settings, counters):
    """The next depth's rays: none without children; else the KEEP children, the ones past
    ``max_depth`` counted as pruned by depth, those under ``min_weight`` by weight (Hall &
    Greenberg 1983), and the total internal reflections of the depths that go on."""
    if children is None:
        return no_rays()
    status, m = children.status, children.status.shape[0]
    if depth + 1 > settings.max_depth:
        unborn = 0
        for i in range(m):
            for c in range(3):
                unborn += status[i, c] != NONE
        counters[PRUNED_DEPTH] += unborn
        return no_rays()
    pruned = tir = 0
    for i in range(m):
        tir += children.tir[i]
        for c in range(3):
            pruned += status[i, c] == PRUNED
    counters[TIR] += tir
    counters[PRUNED_WEIGHT] += pruned
    return spawn(rays, surf, children)


@overload(next_depth, jit_options=INNER)
def _next_depth(children, rays, surf, depth, settings, counters):
    if isinstance(children, types.NoneType):
        return lambda children, rays, surf, depth, settings, counters: no_rays()
    return next_depth


@kernel
def trace_paths(tracer, lights, settings, camera, pass_io, tally):
    """Add into ``pass_io``'s sums everything the pass's ``camera`` rays (a
    :class:`raytrace.kernels.records.Rays`, one per sample, each ray's ``sample`` its row of
    the sums: row by row, or packet by packet where they go COHERENT, ``pass_io.packets``)
    see, depth by depth (``WhittedIntegrator._trace_batch``): a batch grown past
    ``settings.per_pass`` rays (not the camera rays where they go in packets, which are
    traced whole) is cut into chunks that keep each sample's rays together
    (``rays.sample_chunks``), finished one after another, so memory stays bounded by the
    pass size × max depth (a noise-driven round's camera rays may pass the pass size by one
    pixel's samples) and each sample's sum is added up in the same order whatever the pass
    size, the crop or the threads. ``pass_io``: the pass's sums, jitter keys, AOV
    table and camera packets (a :class:`raytrace.kernels.records.PassIO`); ``tally``: its
    counters (a :class:`raytrace.kernels.records.Tally`). The pass ends early, its sums
    incomplete, once ``pass_io.stop[0]`` is not 0 (read before each batch and each light's
    pass: a Ctrl-C or the memory ceiling, ``raytrace.integrator.Stop``)."""
    n = camera.origin.shape[0]
    pending = [camera]
    depths = [0]
    whole = pass_io.packets is not None  # camera rays in packets: traced as one batch
    while len(pending) and pass_io.stop[0] == 0:
        rays = pending.pop()
        depth = depths.pop()
        m = rays.origin.shape[0]
        if m > settings.per_pass and not (whole and depth == 0):
            chunk = np.empty(m, np.int64)
            count = rk.sample_chunks(rays.sample, n, settings.per_pass, chunk)
            out = Rays(np.empty((m, 3)), np.empty((m, 3)), np.empty(m, np.int64),
                       np.empty((m, 3)), np.empty(m, np.int64), np.empty(m, np.int8))
            bounds = rk.gather_chunks(chunk, count, rays, out)
            for c in range(count - 1, -1, -1):
                a, b = bounds[c], bounds[c + 1]
                pending.append(Rays(out.origin[a:b], out.direction[a:b], out.sample[a:b],
                                    out.weight[a:b], out.origin_shape[a:b], out.kind[a:b]))
                depths.append(depth)
            continue
        children = trace_depth(tracer, lights, settings, rays, depth, pass_io, tally)
        if children.origin.shape[0]:
            pending.append(children)
            depths.append(depth + 1)

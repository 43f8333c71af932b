"""Embree's traversal called from compiled code: rays packed into Embree's SoA packets and
``rtcIntersectN`` / ``rtcOccludedN`` called by address (:mod:`raytrace.embree` loads the
library, checks it and hands the addresses over in a
:class:`raytrace.kernels.records.EmbreeScene`).

A function address is an ordinary integer argument, so the machine code holds no address and
numba's cache stays valid from process to process; the call goes through a small intrinsic
(:func:`call4`) that casts the integer to a C function pointer. Traversal calls do no checks
in Embree: the packet layout below is Embree 4.4's (EMBREEX_NOTES.md, last section), and
:func:`raytrace.embree.probe` traces a known ray through these kernels before any render uses
them.

**Packets.** Consecutive rays of a batch fill the lanes of one packet of the library's native
width (16 with AVX-512, 8 with AVX2); a last, partial packet masks its empty lanes off. The
caller says whether the batch is coherent: the raytracer says so for the shadow rays of
camera-ray hits to one point, and gives camera rays in packets of its own, each a block of
the frame's pixels (``raytrace.kernels.camera.frame_packets``) or a noise-driven round's
samples of one pixel (``pixel_packets``); ``RAYTRACE_COHERENT_CAMERA=0`` turns them off.
Embree's COHERENT flag then lets it traverse the packet as a frustum (camera rays in blocks
of 4 × 2 pixels 1.8–2.3× as fast as embreex's single rays here, shadow rays 1.8–2.2×:
docs/decisions.md), which EMBREEX_NOTES.md measured 2× slower than the default on unrelated
rays.

**Ties.** An occlusion answer does not depend on the order Embree meets the triangles in; a
closest hit does where two triangles give the same ``t``, as both do for a ray through the
edge or corner they share. A COHERENT packet meets them in the frustum's order, so which one
it returns depends on the packet's other rays. :func:`closest_hits` therefore traces again,
in a plain packet (which answers each ray as its single-ray call does), every ray whose
COHERENT hit lies within :data:`EDGE` (in barycentrics) of its triangle's edges: 1.1 % of
the camera rays' hits on benchmarks/bench.py's mesh frame. Ties between triangles that meet
away from a shared edge (coplanar overlaps, triangles crossing each other) are not caught:
there a pixel shows the triangle its packet's traversal meets first, and since a packet is
the same rays whichever crop, pass or tile traces it, that choice is the full frame's.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from .jit import inline, kernel

# RTCRayHit's fields in 4-byte words (one ray; an N-wide packet holds field k of lane j at
# word k·N + j): the ray, then the hit (Embree 4.4, RTC_MAX_INSTANCE_LEVEL_COUNT = 1).
ORG, TNEAR, DIR, TIME, TFAR, MASK, ID, FLAGS = 0, 3, 4, 7, 8, 9, 10, 11
NG, U, V, PRIM_ID, GEOM_ID, INST_ID, INST_PRIM_ID = 12, 15, 16, 17, 18, 19, 20
#: Words of an RTCRayHit (an RTCRay is the first :data:`RAY_WORDS`).
RAYHIT1_WORDS, RAY_WORDS = 21, 12
#: Embree's "no geometry" (RTC_INVALID_GEOMETRY_ID as int32), and how :func:`any_hits`
#: marks a ray that something blocks (the other rays get ``FREE``), as embreex's OCCLUDED.
INVALID, BLOCKED, FREE = -1, 0, -1
#: Packets are aligned to 64 bytes (16 words): what a 16-wide packet needs.
ALIGN_WORDS = 16
#: A COHERENT closest hit whose barycentrics u, v or 1 − u − v are below this is traced again
#: without the flag (a possible tie at a shared edge: the module's docstring). Embree's
#: float32 barycentrics are off by ~1e-5 (measured against float64,
#: :func:`raytrace.kernels.accel.refine_hits`); this leaves 100 times that.
EDGE = 1e-3
#: :func:`closest_hits`' ``packets`` for plain packets of consecutive rays.
PLAIN = np.empty(0, np.int64)


@intrinsic
def call4(typingctx, function, a, b, c, d):
    """Call the C function at address ``function`` (an integer) with four pointer-sized
    arguments (integers or pointers), returning nothing."""
    sig = types.void(function, a, b, c, d)

    def codegen(context, builder, signature, args):
        pointer = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [pointer] * 4)
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(x, pointer) for x in args[1:]])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def address(typingctx, array):
    """The address of an array's first element, as an integer."""
    sig = types.int64(array)

    def codegen(context, builder, signature, args):
        a = context.make_array(signature.args[0])(context, builder, args[0])
        return builder.ptrtoint(a.data, ir.IntType(64))

    return sig, codegen


@inline
def aligned(words):
    """A float32 array of ``words`` words whose first lies on a 64-byte boundary."""
    buffer = np.empty(words + ALIGN_WORDS, np.float32)
    skip = (-(address(buffer) // 4)) % ALIGN_WORDS
    return buffer[skip:skip + words]


@inline
def packet_room(embree, coherent):
    """An aligned packet (RTCRayHitN words, N = ``embree.width``), its valid mask, and the
    address of the query arguments: with the COHERENT flag or without."""
    packet = aligned(RAYHIT1_WORDS * embree.width)
    valid = aligned(ALIGN_WORDS).view(np.int32)
    return packet, valid, embree.coherent if coherent else embree.incoherent


@inline
def pack(rays, first, count, width, packet, valid):
    """Rays ``first`` to ``first + count`` of ``rays`` (a
    :class:`raytrace.kernels.records.EmbreeRays`) into the lanes of ``packet`` (an
    RTCRayHitN, float32 words, ``width`` lanes), as embreex set up each ray: tnear 0, time 0,
    every mask bit, no geometry yet; lanes past ``count`` are masked off in ``valid``."""
    words = packet.view(np.int32)
    o, d, far = rays.origin, rays.direction, rays.far
    for j in range(width):
        if j >= count:
            valid[j] = 0
            continue
        i = first + j
        valid[j] = -1
        for k in range(3):
            packet[(ORG + k) * width + j] = o[i, k]
            packet[(DIR + k) * width + j] = d[i, k]
        packet[TNEAR * width + j] = 0.0
        packet[TIME * width + j] = 0.0
        packet[TFAR * width + j] = far[i]
        words[MASK * width + j] = -1
        words[ID * width + j] = 0
        words[FLAGS * width + j] = 0
        words[GEOM_ID * width + j] = INVALID
        words[INST_ID * width + j] = INVALID


@inline
def trace_packet(function, embree, rays, first, count, packet, valid, args):
    """Pack ``count`` rays of ``rays`` from ``first`` on (a packet's worth at most) and call
    Embree's ``function`` (the address of rtcIntersectN or rtcOccludedN) on them."""
    pack(rays, first, count, embree.width, packet, valid)
    call4(function, address(valid), embree.scene, address(packet), args)


@kernel
def closest_hits(embree, rays, packets, out):
    """Embree's closest hit of every ray of ``rays`` (a
    :class:`raytrace.kernels.records.EmbreeRays`) in ``embree`` (a
    :class:`raytrace.kernels.records.EmbreeScene`), in packets: geomID (−1 on a miss),
    primID and the barycentrics u, v into ``out`` (a
    :class:`raytrace.kernels.records.EmbreeHits`), as embreex's ``run(..., output=1)``.
    ``packets`` (int64): empty, plain packets of consecutive rays; else where each COHERENT
    packet starts (and the rays' count last: camera rays, ``kernels.camera.frame_packets`` or
    ``pixel_packets``),
    the hits near an edge traced again without the flag (the module's docstring, "Ties"), so
    that a tie on a shared edge answers as its single ray does."""
    coherent = packets.shape[0] > 0
    width, (packet, valid, args) = embree.width, packet_room(embree, coherent)
    n = rays.far.shape[0]
    again = np.empty(width, np.int32)  # the lanes traced again
    for p in range(packets.shape[0] - 1 if coherent else (n + width - 1) // width):
        first = packets[p] if coherent else p * width
        count = min(width, (packets[p + 1] if coherent else n) - first)
        trace_packet(embree.intersect, embree, rays, first, count, packet, valid, args)
        ties = 0
        for j in range(count):
            if coherent and on_edge(packet, width, j):
                valid[j] = -1  # lane j is traced again
                ties += 1
            else:
                valid[j] = 0
                hit_of(packet, width, j, first + j, out)
        if ties:  # the possible ties, in a plain packet: each as its single-ray call answers
            again[:] = valid[:width]
            pack(rays, first, count, width, packet, valid)
            valid[:width] = again
            call4(embree.intersect, address(valid), embree.scene, address(packet),
                  embree.incoherent)
            for j in range(count):
                if again[j]:
                    hit_of(packet, width, j, first + j, out)


@inline
def on_edge(packet, width, j):
    """Whether lane ``j``'s hit lies within :data:`EDGE` of an edge of its triangle (in
    barycentrics), where another triangle may tie with it; False for a miss."""
    if packet.view(np.int32)[GEOM_ID * width + j] == INVALID:
        return False
    u, v = packet[U * width + j], packet[V * width + j]
    return min(u, v, 1.0 - u - v) < EDGE


@inline
def hit_of(packet, width, j, i, out):
    """Lane ``j``'s answer into row ``i`` of ``out`` (an
    :class:`raytrace.kernels.records.EmbreeHits`)."""
    words = packet.view(np.int32)
    out.geom_id[i] = words[GEOM_ID * width + j]
    out.prim_id[i] = words[PRIM_ID * width + j]
    out.u[i] = packet[U * width + j]
    out.v[i] = packet[V * width + j]


@kernel
def any_hits(embree, rays, coherent, out):
    """Whether anything lies on each ray of ``rays`` before its ``far`` (Embree's occlusion
    query, in packets): ``out[i]`` is :data:`BLOCKED` or :data:`FREE` (int32, as embreex's
    OCCLUDED answer). Embree marks an occluded ray by setting its tfar to −inf."""
    width, (packet, valid, args) = embree.width, packet_room(embree, coherent)
    n = rays.far.shape[0]
    for first in range(0, n, width):
        count = min(width, n - first)
        trace_packet(embree.occluded, embree, rays, first, count, packet, valid, args)
        for j in range(count):
            out[first + j] = BLOCKED if packet[TFAR * width + j] == -np.inf else FREE

"""Rays as structures of arrays: one row per ray.

A :class:`RayBatch` flows through the pipeline: the camera makes one, the accelerator
intersects it, the integrator shades the hits and spawns the next depth's batch. Whitted's sum
``I = local + kr·I_r + kt·I_t`` is linear in the child rays, so every ray carries the product of
the weights along its path and the index of the pixel sample it belongs to; contributions are
added to that sample (Whitted 1980, in wavefront form as in pbrt-v4's wavefront integrator).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kernels.kinds import CAMERA, KIND_NAMES, NO_SHAPE, REFLECTION, REFRACTION, SEE_THROUGH  # noqa: F401
from .kernels.rays import (
    take_rows,
)
from .kernels.records import CameraPackets, Rays


@dataclass
class RayBatch:
    """A batch of ``n`` rays.

    Attributes
    ----------
    origin : (n, 3) float64
        Start points, camera-relative world coordinates.
    direction : (n, 3) float64
        Unit directions.
    sample : (n,) int64
        Index of the pixel sample (within the current pass) the ray contributes to.
    weight : (n, 3) float64
        Product of the kr, kt, opacity factors along the path (per RGB channel).
    depth : int
        Recursion depth shared by the batch: camera rays are depth 0.
    origin_shape : (n,) int64
        The analytic shape (sphere or plane index into the shape table) the ray starts on,
        or :data:`NO_SHAPE`; it lets analytic intersection avoid self-hits without an epsilon.
    kind : (n,) int8
        CAMERA, REFLECTION, REFRACTION or SEE_THROUGH.
    packets : CameraPackets or None
        Camera rays only: the packets Embree traces them in, every sample of each block of
        the frame that holds one of them (:func:`raytrace.kernels.camera.frame_packets`),
        or a noise-driven round's, a pixel's samples each
        (:func:`raytrace.kernels.camera.pixel_packets`); None: plain packets. A batch taken
        from this one has none, and one that has them is traced whole, however long.
    """

    origin: np.ndarray
    direction: np.ndarray
    sample: np.ndarray
    weight: np.ndarray
    depth: int
    origin_shape: np.ndarray
    kind: np.ndarray
    packets: CameraPackets | None = None

    def __len__(self) -> int:
        return self.origin.shape[0]

    @property
    def record(self) -> Rays:
        """The columns as the kernels take them (:class:`raytrace.kernels.records.Rays`)."""
        return Rays(self.origin, self.direction, self.sample, self.weight, self.origin_shape,
                    self.kind)

    def take(self, index: np.ndarray | slice) -> RayBatch:
        """The rays selected by a boolean mask or an index array (compaction), or a slice
        (views, no copy)."""
        if isinstance(index, slice):
            return RayBatch(self.origin[index], self.direction[index], self.sample[index],
                            self.weight[index], self.depth, self.origin_shape[index],
                            self.kind[index])
        index = np.asarray(index)
        rows = np.flatnonzero(index) if index.dtype == bool else index.astype(np.int64)
        return RayBatch(take_rows(self.origin, rows), take_rows(self.direction, rows),
                        self.sample[rows], take_rows(self.weight, rows), self.depth,
                        self.origin_shape[rows], self.kind[rows])

    @staticmethod
    def empty(depth: int = 0) -> RayBatch:
        z3 = np.zeros((0, 3))
        return RayBatch(z3, z3.copy(), np.zeros(0, np.int64), z3.copy(), depth,
                        np.zeros(0, np.int64), np.zeros(0, np.int8))



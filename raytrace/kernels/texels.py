"""Image codes to linear texels: an 8- or 16-bit image that
:class:`raytrace.readers.texture.Texels` keeps as its codes, decoded by the material table
(:func:`raytrace.tables.texel_array`) straight into the texel array the kernels read.

:func:`decode_codes` looks each code of an RGBA image up in the colour table (R, G, B: the
sRGB decoding of IEC 61966-2-1, or c / (2^bits − 1) for linear data) or the alpha table
(always c / (2^bits − 1)), as ``Texels.floats`` does with numpy's ``take``, which first
widens every code to a 64-bit index: 0.066 s for a 2048² image against this kernel's 0.013 s
(docs/performance.md, "Model files").
"""

from __future__ import annotations

from .jit import kernel


@kernel
def decode_codes(colour, alpha, codes, out):
    """``out[i, j, c] = colour[codes[i, j, c]]`` for c = 0, 1, 2 and ``alpha[codes[i, j,
    3]]`` for c = 3: ``codes`` (H, W, 4) uint8 or uint16, the tables (2^bits,) float32,
    ``out`` (H, W, 4) float32."""
    for i in range(codes.shape[0]):
        for j in range(codes.shape[1]):
            for c in range(3):
                out[i, j, c] = colour[codes[i, j, c]]
            out[i, j, 3] = alpha[codes[i, j, 3]]

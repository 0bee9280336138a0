"""Image files: tone-mapped PNGs for people, float OpenEXR for programs, figures as PNG.

The OpenEXR writer is plain NumPy and zlib (no renderer, no OpenEXR
library): a single-part scanline file with three float32 channels ``B, G,
R`` and ZIP compression, which Mitsuba, OpenEXR, OpenImageIO and every
HDR viewer read. Display conventions (tone mapping, exposure) live in
:mod:`sparselt.images`.

References
----------
"OpenEXR File Layout" and "Technical Introduction to OpenEXR" (Academy
Software Foundation, openexr.com): the magic number, the header attributes,
the line offset table, scanline blocks and the ZIP compressor's reordering
and predictor.
"""

from __future__ import annotations

import io
import struct
import zlib

import numpy as np

from .images import srgb_tonemap

_EXR_MAGIC = 20000630
_EXR_VERSION = 2  # single-part scanline file, no flags
_FLOAT_PIXELS = 2  # the channel list's pixel type of 32-bit floats
_ZIP_COMPRESSION = 3  # zlib over blocks of 16 scanlines
_ZIP_LINES_PER_BLOCK = 16
_INCREASING_Y = 0
_CHANNELS = ("B", "G", "R")  # the channel list is sorted by name; data are stored in its order


def _attribute(name, kind, value):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def _exr_header(width, height):
    channels = b"".join(name.encode() + b"\0" + struct.pack("<iB3xii", _FLOAT_PIXELS, 0, 1, 1) for name in _CHANNELS)
    window = struct.pack("<iiii", 0, 0, width - 1, height - 1)
    return b"".join([
        _attribute("channels", "chlist", channels + b"\0"),
        _attribute("compression", "compression", struct.pack("<B", _ZIP_COMPRESSION)),
        _attribute("dataWindow", "box2i", window),
        _attribute("displayWindow", "box2i", window),
        _attribute("lineOrder", "lineOrder", struct.pack("<B", _INCREASING_Y)),
        _attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        _attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)),
    ]) + b"\0"


def _zip_block(raw):
    """OpenEXR's ZIP compressor on one block's bytes: the bytes split into even and odd positions, each byte
    replaced by its difference to the previous one plus 128 (mod 256), then zlib; the raw bytes if not smaller."""
    data = np.frombuffer(raw, dtype=np.uint8)
    reordered = np.concatenate([data[0::2], data[1::2]])
    predicted = reordered.copy()
    predicted[1:] = (reordered[1:].astype(np.int16) - reordered[:-1] + 128).astype(np.uint8)
    compressed = zlib.compress(predicted.tobytes())
    return compressed if len(compressed) < len(raw) else raw


def exr_bytes(image):
    """A ``(height, width, 3)`` RGB image as OpenEXR file bytes: float32 channels, ZIP compression.

    Parameters
    ----------
    image : array_like, shape (height, width, 3)
        Linear RGB; converted to float32 (NaN and infinities kept as they are).

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        ``image`` is not ``(height, width, 3)`` with a positive height and width.

    Notes
    -----
    Lossless: reading the file back gives the float32 values bit for bit.
    Each block of up to 16 scanlines holds, per scanline, the ``B``, ``G``
    and ``R`` values of every pixel, little-endian.
    """
    pixels = np.asarray(image)
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.shape[0] < 1 or pixels.shape[1] < 1:
        raise ValueError(f"an EXR image must be (height, width, 3) with height and width >= 1, "
                         f"got shape {pixels.shape}")
    height, width = pixels.shape[:2]
    # Per scanline, one row of each channel in the channel list's order (B, G, R), as little-endian float32.
    planar = np.ascontiguousarray(pixels.astype("<f4")[:, :, ::-1].transpose(0, 2, 1))
    blocks = []
    for first in range(0, height, _ZIP_LINES_PER_BLOCK):
        data = _zip_block(planar[first:first + _ZIP_LINES_PER_BLOCK].tobytes())
        blocks.append(struct.pack("<ii", first, len(data)) + data)
    header = struct.pack("<ii", _EXR_MAGIC, _EXR_VERSION) + _exr_header(width, height)
    offsets, position = [], len(header) + 8 * len(blocks)
    for block in blocks:
        offsets.append(position)
        position += len(block)
    return header + struct.pack(f"<{len(offsets)}Q", *offsets) + b"".join(blocks)


def write_exr(path, image):
    """Write a ``(height, width, 3)`` image as OpenEXR (:func:`exr_bytes`), atomically (a full disk names the file)."""
    from .provenance import atomic_write_bytes

    atomic_write_bytes(path, exr_bytes(image))


def png_bytes(image, *, exposure=1.0):
    """A linear ``(height, width, 3)`` image, tone-mapped (:func:`sparselt.images.srgb_tonemap`), as PNG bytes."""
    from matplotlib import image as matplotlib_image

    buffer = io.BytesIO()
    matplotlib_image.imsave(buffer, srgb_tonemap(image, exposure), format="png")
    return buffer.getvalue()


def figure_bytes(figure, **options):
    """A matplotlib figure as PNG bytes, cropped to what it draws (legends outside the axes included); closed."""
    import matplotlib.pyplot as pyplot

    options.setdefault("bbox_inches", "tight")
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", **options)
    pyplot.close(figure)
    return buffer.getvalue()

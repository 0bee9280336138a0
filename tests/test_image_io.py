"""Image files: the NumPy OpenEXR writer is read back bit for bit by Mitsuba's (OpenEXR's) reader."""

import struct
import zlib

import numpy as np
import pytest

from sparselt.image_io import exr_bytes, png_bytes, write_exr

# One line, one block (16 lines), a partial last block, a tall thin and a wide image.
SHAPES = [(1, 1), (1, 9), (16, 5), (17, 3), (40, 33), (70, 2)]


def _read_with_mitsuba(path):
    from sparselt.rendering.mitsuba import initialize

    mi = initialize()
    bitmap = mi.Bitmap(str(path))
    return bitmap, np.array(bitmap)


@pytest.mark.parametrize("height, width", SHAPES)
def test_exr_round_trips_through_mitsubas_reader_bit_for_bit(tmp_path, height, width):
    rng = np.random.default_rng(height * 100 + width)
    image = (rng.standard_normal((height, width, 3)) * 10.0 ** rng.integers(-6, 6, (height, width, 3)))
    image = image.astype(np.float32)
    image.flat[0] = np.inf
    image.flat[-1] = np.nan
    write_exr(str(tmp_path / "image.exr"), image)
    bitmap, read = _read_with_mitsuba(tmp_path / "image.exr")
    assert read.shape == (height, width, 3) and read.dtype == np.float32
    assert read.view(np.uint32).tobytes() == image.view(np.uint32).tobytes()
    assert [channel.name for channel in bitmap.struct_()] == ["R", "G", "B"]


def test_smooth_images_are_compressed_and_noise_falls_back_to_raw_blocks():
    height, width = 64, 64
    smooth = np.tile(np.linspace(0, 1, width, dtype=np.float32)[None, :, None], (height, 1, 3))
    assert len(exr_bytes(smooth)) < height * width * 12 / 10
    single = exr_bytes(np.full((1, 1, 3), 0.5, dtype=np.float32))
    # The only block holds its 12 raw bytes (zlib would make them longer): y = 0, size 12, then B, G, R.
    assert single[-20:] == struct.pack("<ii", 0, 12) + np.full(3, 0.5, dtype="<f4").tobytes()


def test_exr_layout_follows_the_openexr_file_layout():
    """Magic number, version 2, the header's attributes, the offset table and a ZIP block decoded by hand."""
    image = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    data = exr_bytes(image)
    assert struct.unpack("<ii", data[:8]) == (20000630, 2)
    last = data.index(b"screenWindowWidth\0float\0") + len(b"screenWindowWidth\0float\0")
    assert data[last:last + 8] == struct.pack("<if", 4, 1.0) and data[last + 8:last + 9] == b"\0"  # header ends
    header_end = last + 9
    for attribute in (b"channels\0chlist\0", b"compression\0compression\0\x01\x00\x00\x00\x03",
                      b"dataWindow\0box2i\0\x10\x00\x00\x00" + struct.pack("<iiii", 0, 0, 2, 1),
                      b"lineOrder\0lineOrder\0\x01\x00\x00\x00\x00"):
        assert attribute in data[:header_end]
    (offset,) = struct.unpack("<Q", data[header_end:header_end + 8])
    assert offset == header_end + 8
    y, size = struct.unpack("<ii", data[offset:offset + 8])
    block = data[offset + 8:offset + 8 + size]
    assert y == 0 and size == len(block) and offset + 8 + size == len(data)
    assert size < 2 * 3 * 3 * 4  # compressed: zlib, then undo the predictor and the even/odd reordering
    predicted = np.frombuffer(zlib.decompress(block), dtype=np.uint8).astype(np.int64)
    reordered = (np.cumsum(np.concatenate([[predicted[0]], predicted[1:] - 128])) % 256).astype(np.uint8)
    half = (reordered.size + 1) // 2
    raw = np.empty_like(reordered)
    raw[0::2], raw[1::2] = reordered[:half], reordered[half:]
    lines = np.frombuffer(raw.tobytes(), dtype="<f4").reshape(2, 3, 3)  # per line: B, G, R rows
    np.testing.assert_array_equal(lines[:, ::-1].transpose(0, 2, 1), image)


@pytest.mark.parametrize("shape", [(4, 4), (4, 4, 4), (0, 3, 3), (3, 0, 3), (2, 2, 3, 1)])
def test_exr_needs_a_height_by_width_by_three_image(shape):
    with pytest.raises(ValueError, match=r"\(height, width, 3\)"):
        exr_bytes(np.zeros(shape, dtype=np.float32))


def test_exr_bytes_are_a_function_of_the_pixels():
    image = np.random.default_rng(3).random((20, 7, 3))
    assert exr_bytes(image) == exr_bytes(image.astype(np.float32)) == exr_bytes(image.tolist())


def test_png_bytes_are_a_png():
    data = png_bytes(np.ones((3, 4, 3), dtype=np.float32), exposure=0.5)
    assert data[:8] == b"\x89PNG\r\n\x1a\n"

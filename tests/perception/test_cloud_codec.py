"""PointCloud2 byte layouts: what the sim writes and what real drivers send must both decode."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.perception.cloud_codec import (
    CloudFormatError,
    Field,
    decode,
    encode,
    pack_rgb,
    unpack_rgb,
)

FLOAT32, FLOAT64, UINT8 = 7, 8, 2


def test_rgb_packing_both_ways_matches_the_driver_byte_order():
    rgb = np.array([[0x11, 0x22, 0x33], [255, 0, 128]], dtype=np.uint8)
    packed = pack_rgb(rgb)
    assert packed.dtype == np.float32
    # Little-endian bytes in memory are B, G, R, A (alpha 0), as PointCloud2Iterator "r"/"g"/"b" write them.
    assert packed[:1].tobytes() == bytes([0x33, 0x22, 0x11, 0x00])
    np.testing.assert_array_equal(unpack_rgb(packed), rgb)
    every_value = np.stack(np.meshgrid(np.arange(0, 256, 15), np.arange(0, 256, 15), np.arange(0, 256, 15)), -1).reshape(-1, 3)
    np.testing.assert_array_equal(unpack_rgb(pack_rgb(every_value.astype(np.uint8))), every_value)


def test_encode_writes_the_design_layout():
    xyz = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    xyz[0, 1] = np.nan
    rgb = np.full((2, 3, 3), 7, dtype=np.uint8)
    cloud = encode(xyz, rgb)
    assert [(f.name, f.offset, f.datatype) for f in cloud.fields] == [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("rgb", 16, 7)]
    assert (cloud.height, cloud.width, cloud.point_step, cloud.row_step) == (2, 3, 32, 96)
    assert len(cloud.data) == 2 * 96
    xyz_only = encode(xyz)
    assert xyz_only.point_step == 16 and [f.name for f in xyz_only.fields] == ["x", "y", "z"]
    decoded = decode(cloud.fields, cloud.data, 2, 3, 32, 96)
    np.testing.assert_array_equal(decoded.xyz, xyz.reshape(-1, 3))
    np.testing.assert_array_equal(decoded.rgb, rgb.reshape(-1, 3))


def test_decode_padding_row_step_float64_and_separate_colour_fields():
    n, point_step, row_step = 4, 40, 4 * 40 + 12  # per-point padding and per-row padding
    record = np.zeros((2, row_step), dtype=np.uint8)
    xyz = np.arange(2 * n * 3, dtype=np.float64).reshape(2, n, 3) / 10
    colours = np.arange(2 * n * 3, dtype=np.uint8).reshape(2, n, 3) * 9
    for row in range(2):
        for i in range(n):
            base = i * point_step
            record[row, base + 8 : base + 32] = np.frombuffer(xyz[row, i].tobytes(), np.uint8)
            record[row, base + 33 : base + 36] = colours[row, i]
    fields = [Field("x", 8, FLOAT64), Field("y", 16, FLOAT64), Field("z", 24, FLOAT64),
              Field("r", 33, UINT8), Field("g", 34, UINT8), Field("b", 35, UINT8)]
    decoded = decode(fields, record.tobytes(), 2, n, point_step, row_step)
    np.testing.assert_allclose(decoded.xyz, xyz.reshape(-1, 3), rtol=1e-6)
    np.testing.assert_array_equal(decoded.rgb, colours.reshape(-1, 3))


def test_decode_big_endian_and_packed_uint32_rgba():
    xyz = np.array([[1.5, -2.0, 3.25]], dtype=">f4")
    rgba = np.array([(0x10 << 16) | (0x20 << 8) | 0x30 | (0xFF << 24)], dtype=">u4")
    data = xyz.tobytes() + b"\0" * 4 + rgba.tobytes()
    fields = [Field("x", 0, FLOAT32), Field("y", 4, FLOAT32), Field("z", 8, FLOAT32), Field("rgba", 16, 6)]
    decoded = decode(fields, data, 1, 1, 20, 20, is_bigendian=True)
    np.testing.assert_array_equal(decoded.xyz, [[1.5, -2.0, 3.25]])
    np.testing.assert_array_equal(decoded.rgb, [[0x10, 0x20, 0x30]])


def test_azure_kinect_xyz_only_organized_cloud():
    xyz = np.full((288, 320, 3), np.nan, dtype=np.float32)
    xyz[100:200, 50:250] = [0.1, 0.2, 1.0]
    cloud = encode(xyz)
    decoded = decode(cloud.fields, cloud.data, 288, 320, 16, 320 * 16)
    assert decoded.rgb is None and decoded.xyz.shape == (288 * 320, 3)
    assert np.isfinite(decoded.xyz).all(axis=1).sum() == 100 * 200


@pytest.mark.parametrize(
    "fields, data, message",
    [
        ([Field("x", 0, FLOAT32), Field("y", 4, FLOAT32)], b"\0" * 16, "missing field(s) z"),
        ([Field("x", 0, FLOAT32), Field("y", 4, FLOAT32), Field("z", 8, FLOAT32)], b"\0" * 8, "data has 8 bytes"),
        ([Field("x", 0, FLOAT32), Field("y", 4, FLOAT32), Field("z", 14, FLOAT32)], b"\0" * 16, "exceeds point_step"),
        ([Field("x", 0, FLOAT32), Field("y", 4, FLOAT32), Field("z", 8, 42)], b"\0" * 16, "unknown datatype"),
    ],
)
def test_unreadable_payloads_raise_a_clear_error(fields, data, message):
    with pytest.raises(CloudFormatError, match=message.replace("(", r"\(").replace(")", r"\)")):
        decode(fields, data, 1, 1, 16, 16)

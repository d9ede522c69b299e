"""Point-cloud files read into points (arduinobot.client.cloud_files)."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from arduinobot.client.cloud_files import read_cloud_file
from arduinobot.contract.errors import InvalidRequest

PTS = np.array([[0.1, 0.2, 0.3], [-1.5, 2.25, 0.0], [3.0, -4.0, 5.5], [np.nan, 1.0, 2.0]])


def test_binary_ply_written_by_hand(tmp_path):
    f = tmp_path / "c.ply"
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
            "property float y\nproperty float z\nproperty uchar red\nend_header\n")
    body = b"".join(struct.pack("<fffB", *p, 200) for p in PTS)
    f.write_bytes(head.encode() + body)
    np.testing.assert_allclose(read_cloud_file(f), PTS.astype(np.float32), equal_nan=True)


def test_ascii_pcd_written_by_hand(tmp_path):
    f = tmp_path / "c.pcd"
    rows = "\n".join(f"{x} {y} {z} 0.5" for x, y, z in PTS)
    f.write_text("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\n"
                 "TYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 4\nHEIGHT 1\n"
                 "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n" + rows + "\n")
    np.testing.assert_allclose(read_cloud_file(f), PTS.astype(np.float32), equal_nan=True)


def test_binary_pcd_with_fields_out_of_order(tmp_path):
    f = tmp_path / "c.pcd"
    head = ("VERSION 0.7\nFIELDS z rgb x y\nSIZE 4 4 4 4\nTYPE F U F F\nCOUNT 1 1 1 1\n"
            "WIDTH 4\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA binary\n")
    body = b"".join(struct.pack("<fIff", p[2], 7, p[0], p[1]) for p in PTS)
    f.write_bytes(head.encode() + body)
    np.testing.assert_allclose(read_cloud_file(f), PTS.astype(np.float32), equal_nan=True)


@pytest.mark.parametrize("name,text", [
    ("c.xyz", "0.1 0.2 0.3\n-1.5 2.25 0\n3 -4 5.5 9 9\nnan 1 2\n"),
    ("c.csv", "x,y,z,intensity\n0.1,0.2,0.3,1\n-1.5,2.25,0,1\n3,-4,5.5,1\nnan,1,2,1\n"),
])
def test_text_clouds(tmp_path, name, text):
    f = tmp_path / name
    f.write_text(text)
    np.testing.assert_allclose(read_cloud_file(f), PTS, equal_nan=True)


@pytest.mark.parametrize("name,content", [
    ("c.obj", b"v 0 0 0\n"),
    ("c.csv", b"1,2\n3,4\n"),
    ("c.xyz", b"a b c\nd e f\n"),
    ("c.pcd", b"VERSION 0.7\nFIELDS a b\n"),
    ("c.ply", b"not a ply at all"),
])
def test_bad_files_are_refused_naming_the_file(tmp_path, name, content):
    f = tmp_path / name
    f.write_bytes(content)
    with pytest.raises(InvalidRequest) as e:
        read_cloud_file(f)
    assert e.value.field == "file"

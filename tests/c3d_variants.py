"""C3D files rewritten as other C3D variants, to test and bench the reader against ezc3d:
int16 storage, DEC (VAX floats) and MIPS (big-endian) processors, from an Intel float-storage
file written by ezc3d (which writes no other kind)."""

from __future__ import annotations

import numpy as np

DEC, MIPS = 85, 86


def _records(data: bytes):
    """(name, group id, offset field, parameter type, data start, count) of each record."""
    start = (data[0] - 1) * 512
    pos = start + 4
    while True:
        nlen, gid = np.frombuffer(data, np.int8, 2, pos).tolist()
        if nlen == 0:
            return
        end = pos + 2 + abs(nlen)
        kind, ndims, count = 0, 0, 0
        if gid > 0:
            kind, ndims = int(np.frombuffer(data, np.int8, 1, end + 2)[0]), data[end + 3]
            count = int(np.prod(list(data[end + 4 : end + 4 + ndims]))) if ndims else 1
        yield data[pos + 2 : end].decode(), gid, end, kind, end + 4 + ndims, count
        offset = int(np.frombuffer(data, "<u2", 1, end)[0])
        if offset == 0:
            return
        pos = end + offset


def dec(b: np.ndarray) -> np.ndarray:
    """IEEE little-endian float bytes (..., 4) → DEC (VAX F) bytes, as ezc3d reads them back."""
    out = b[..., [2, 3, 0, 1]].copy()
    out[..., 1] = b[..., 3] + np.uint8(1)
    return out


def convert(data: bytes, processor: int) -> bytes:
    """An Intel float-storage C3D (no analogs' int values) rewritten for DEC or MIPS."""
    out = bytearray(data)
    start = (data[0] - 1) * 512
    out[start + 3] = processor

    def floats(at: int, n: int) -> None:
        b = np.frombuffer(data, np.uint8, 4 * n, at).reshape(n, 4)
        out[at : at + 4 * n] = (dec(b) if processor == DEC else b[:, ::-1]).tobytes()

    def words(at: int, n: int) -> None:
        if processor == MIPS:
            out[at : at + 2 * n] = np.frombuffer(data, "<i2", n, at).astype(">i2").tobytes()

    words(2, 5), floats(12, 1), words(16, 2), floats(20, 1)
    for _, _, end, kind, body, count in _records(data):
        words(end, 1)
        if kind == 4:
            floats(body, count)
        elif kind == 2:
            words(body, count)
    at = (int(np.frombuffer(data, "<u2", 1, 16)[0]) - 1) * 512
    floats(at, (len(data) - at) // 4)
    return bytes(out)


def to_int16(data: bytes, scale: float) -> bytes:
    """A float-storage C3D rewritten as int16 words scaled by ``scale`` (POINT:SCALE is
    already ``scale``): x, y, z / scale; the residual word's high byte the residual, its low
    byte the camera mask (all-ones word: not seen, NaN too); analog samples rounded."""
    out = bytearray(data)
    out[12:16] = np.float32(scale).tobytes()
    records = list(_records(data))
    point = next(-gid for name, gid, *_ in records if name == "POINT" and gid < 0)
    (body,) = [r[4] for r in records if r[0] == "SCALE" and r[1] == point]
    out[body : body + 4] = np.float32(scale).tobytes()  # ezc3d wrote it negative
    at = (int(np.frombuffer(data, "<u2", 1, 16)[0]) - 1) * 512
    points = int(np.frombuffer(data, "<u2", 1, 2)[0])
    analog = int(np.frombuffer(data, "<u2", 1, 4)[0])
    n = (len(data) - at) // (4 * (4 * points + analog))  # and what padding holds
    frames = np.frombuffer(data, "<f4", n * (4 * points + analog), at).reshape(n, -1)
    pts = frames[:, : 4 * points].reshape(n, points, 4).astype(float)
    seen = (pts[..., 3] >= 0) & ~np.isnan(pts[..., :3]).any(axis=2)
    word = np.floor(np.where(seen, pts[..., 3], 0.0) + 0.5).astype(np.int64)
    ints = np.zeros((n, 4 * points + analog), "<i2")
    xyz = np.where(seen[..., None], np.round(np.nan_to_num(pts[..., :3]) / scale), 0)
    last = np.where(seen, ((word >> 8) & 0x7F) << 8 | word & 0xFF, -1)
    ints[:, : 4 * points] = np.concatenate([xyz, last[..., None]], axis=2).reshape(n, -1)
    ints[:, 4 * points :] = np.round(frames[:, 4 * points :])
    return bytes(out[:at]) + ints.tobytes()

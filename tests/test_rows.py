"""Row gathers (gsverse_format.rows): the C gather gives numpy's rows, byte for byte, for
every dtype and layout it takes, leaves the rest to numpy, and refuses calls that would read
or write outside its buffers."""
from __future__ import annotations

import numpy as np
import pytest

from gsverse_format import rows


class Spy:
    """The real extension, counting the gathers it is asked for."""

    def __init__(self, module):
        self.module, self.calls = module, 0

    def gather(self, *args):
        self.calls += 1
        return self.module.gather(*args)


@pytest.fixture
def spy(monkeypatch):
    module = rows._module()
    assert module is not None, "gsverse_format._rows was not built"
    s = Spy(module)
    monkeypatch.setattr(rows, "_module", lambda: s)
    monkeypatch.setattr(rows, "NATIVE_MIN_BYTES", 0)        # every gather in C
    return s


def arrays(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    structured = np.zeros(n, [("a", "<f4"), ("b", "u1"), ("c", "<i8")])
    structured["a"], structured["c"] = rng.normal(size=n), rng.integers(-9, 9, n)
    return {"sh": rng.normal(size=(n, 16, 3)).astype(np.float32),
            "means": rng.normal(size=(n, 3)).astype(np.float32),
            "opacity": rng.normal(size=n).astype(np.float32),
            "float64": rng.normal(size=(n, 2)),
            "face": rng.integers(0, 2**32, n, dtype=np.uint32),
            "bool": rng.uniform(size=(n, 5)) < 0.5,
            "bytes": rng.integers(0, 256, (n, 7), dtype=np.uint8),
            "structured": structured,
            "big-endian": rng.normal(size=(n, 3)).astype(">f8")}


def test_the_extension_was_built():
    assert rows.native_rows_available()


@pytest.mark.parametrize("threads", ["1", "3"])
def test_take_rows_in_c_equals_numpy(spy, monkeypatch, threads):
    monkeypatch.setenv("GSVERSE_THREADS", threads)
    rng = np.random.default_rng(1)
    n = 9_000                                     # three blocks of the C loop, the last partial
    for name, a in arrays(n, rng).items():
        for index in (rng.permutation(n), rng.integers(0, n, 20_000), rng.integers(0, n, 7),
                      rng.permutation(n).astype(np.uint32), np.arange(0), np.full(5, n - 1)):
            before = spy.calls
            got = rows.take_rows(a, index)
            assert spy.calls == before + 1, name            # done in C
            expected = np.take(a, index, axis=0)
            assert got.dtype == expected.dtype and got.shape == expected.shape, name
            assert got.tobytes() == expected.tobytes(), name


def test_take_rows_leaves_to_numpy_what_the_c_gather_does_not_take(spy):
    rng = np.random.default_rng(2)
    a = rng.normal(size=(50, 4)).astype(np.float32)
    mask = rng.uniform(size=50) < 0.3
    for index in (mask, slice(3, 40, 2), [4, 1, 1], np.array([-1, 0, -50])):
        assert rows.take_rows(a, index).tobytes() == a[index].tobytes()
    # not C-contiguous: numpy's take (no C call); negative indices: numpy's take after the
    # C gather refused them
    calls = spy.calls
    assert rows.take_rows(a[:, ::2], np.arange(3)).tobytes() == a[:3, ::2].tobytes()
    assert spy.calls == calls
    for bad in (np.array([0, 50]), np.array([-51])):           # numpy's own error
        with pytest.raises(IndexError):
            rows.take_rows(a, bad)


def test_small_gathers_stay_in_numpy(monkeypatch):
    module = rows._module()
    s = Spy(module)
    monkeypatch.setattr(rows, "_module", lambda: s)
    a = np.arange(300, dtype=np.float32).reshape(100, 3)
    order = np.arange(100)[::-1].copy()
    assert rows.take_rows(a, order).tobytes() == a[order].tobytes()
    assert s.calls == 0                  # 1,200 bytes: below NATIVE_MIN_BYTES
    big = np.zeros((rows.NATIVE_MIN_BYTES // 12 + 1, 3), np.float32)
    rows.take_rows(big, np.arange(len(big)))
    assert s.calls == 1


@pytest.mark.parametrize("blocks", [1, 2, 3, 5])
@pytest.mark.parametrize("native", [True, False])
def test_permute_in_place_equals_the_gather(monkeypatch, blocks, native):
    monkeypatch.setattr(rows, "PERMUTE_BLOCKS", blocks)
    monkeypatch.setattr(rows, "NATIVE_MIN_BYTES", 0 if native else 1 << 62)
    rng = np.random.default_rng(3)
    for a in (rng.normal(size=(5_000, 16, 3)).astype(np.float32),
              rng.integers(0, 9, (4_999, 15), dtype=np.int16)):
        order = rng.permutation(len(a))
        expected = a[order]
        address = a.__array_interface__["data"][0]
        rows.permute_rows_in_place(a, order)
        assert a.__array_interface__["data"][0] == address
        assert a.tobytes() == expected.tobytes()


def test_the_c_gather_refuses_calls_that_would_leave_its_buffers():
    from gsverse_format import _rows

    src = np.arange(12, dtype=np.uint8)                       # 3 rows of 4 bytes
    dst = np.empty(4, np.uint8)
    order = np.array([2, 0], np.int64)
    _rows.gather(src, 4, 1, 2, order, dst, 1)
    assert list(dst) == [9, 10, 1, 2]
    for row_bytes, offset, width in ((0, 0, 1), (4, 3, 2), (4, -1, 2), (4, 0, 0)):
        with pytest.raises(ValueError, match="layout"):
            _rows.gather(src, row_bytes, offset, width, order, dst, 1)
    with pytest.raises(ValueError, match="sizes"):
        _rows.gather(src, 5, 0, 2, order, dst, 1)             # 12 bytes are not rows of 5
    with pytest.raises(ValueError, match="sizes"):
        _rows.gather(src, 4, 0, 2, order, np.empty(5, np.uint8), 1)
    for bad in ([3, 0], [0, -1]):
        dst[:] = 7
        with pytest.raises(ValueError, match="range"):
            _rows.gather(src, 4, 0, 2, np.array(bad, np.int64), dst, 1)
        assert list(dst) == [7, 7, 7, 7]                     # nothing written
    with pytest.raises(TypeError, match="int64"):
        _rows.gather(src, 4, 0, 2, order.astype(np.int32), dst, 1)
    with pytest.raises((TypeError, ValueError, BufferError)):
        _rows.gather(src, 4, 0, 2, order, np.empty(4, np.uint8)[::-1], 1)   # not contiguous
    with pytest.raises((TypeError, ValueError, BufferError)):
        _rows.gather(src, 4, 0, 2, order, np.frombuffer(b"abcd", np.uint8), 1)  # read-only


class ColumnSpy:
    """The real extension, counting the column copies it is asked for."""

    def __init__(self, module):
        self.module, self.calls = module, 0

    def columns(self, *args):
        self.calls += 1
        return self.module.columns(*args)


@pytest.mark.parametrize("threads", ["1", "3"])
def test_contiguous_rows_of_column_views_equal_numpy(monkeypatch, threads):
    """Views of some columns of a C-contiguous array are copied in C, byte for byte numpy's
    copy, for any block of rows; every other view is left to numpy."""
    monkeypatch.setenv("GSVERSE_THREADS", threads)
    s = ColumnSpy(rows._module())
    monkeypatch.setattr(rows, "_module", lambda: s)
    monkeypatch.setattr(rows, "NATIVE_MIN_BYTES", 0)
    rng = np.random.default_rng(4)
    n = 9_000
    sh = rng.normal(size=(n, 16, 3)).astype(np.float32)
    structured = arrays(n, rng)["structured"]
    in_c = [sh[:, 0, :], sh[:, 15, :], sh[:, 3:7, :], sh[:, 5, 1:], structured["c"],
            rng.normal(size=(n, 4, 2))[:, 1], rng.integers(0, 256, (n, 7), np.uint8)[:, 2:5]]
    in_numpy = [sh[:, :, 1], sh[::2, 0, :], sh[:, 0, :].T, sh[:, 0, ::2], sh.reshape(-1)[1:],
                sh[:, 0, :].copy()]
    for views, in_native in ((in_c, True), (in_numpy, False)):
        for v in views:
            for start, stop in ((0, len(v)), (1, len(v) - 1), (4095, 4097), (7, 7)):
                before = s.calls
                got = rows.contiguous_rows(v, start, stop)
                expected = np.ascontiguousarray(v[start:stop])
                assert got.flags.c_contiguous and got.dtype == expected.dtype
                assert got.shape == expected.shape and got.tobytes() == expected.tobytes()
                # a block that is already contiguous (no rows, or one) needs no copy
                copied = in_native and not v[start:stop].flags.c_contiguous
                assert s.calls == before + copied, (v.shape, v.strides, start, stop)
        assert not in_native or s.calls > 0


def test_the_c_column_copy_refuses_calls_that_would_leave_its_buffers():
    from gsverse_format import _rows

    src = np.arange(12, dtype=np.uint8)                       # 3 rows of 4 bytes
    dst = np.empty(4, np.uint8)
    _rows.columns(src, 4, 1, 2, 1, dst, 1)
    assert list(dst) == [5, 6, 9, 10]
    for row_bytes, offset, width, first in ((0, 0, 1, 0), (4, 3, 2, 0), (4, -1, 2, 0),
                                            (4, 0, 0, 0), (4, 0, 2, -1)):
        with pytest.raises(ValueError, match="layout"):
            _rows.columns(src, row_bytes, offset, width, first, dst, 1)
    with pytest.raises(ValueError, match="sizes"):
        _rows.columns(src, 5, 0, 2, 0, dst, 1)                # 12 bytes are not rows of 5
    with pytest.raises(ValueError, match="sizes"):
        _rows.columns(src, 4, 0, 2, 0, np.empty(5, np.uint8), 1)
    dst[:] = 7
    for first in (2, 3, 2**62):
        with pytest.raises(ValueError, match="range"):
            _rows.columns(src, 4, 0, 2, first, dst, 1)        # rows 2, 3: past the end
        assert list(dst) == [7, 7, 7, 7]                      # nothing written
    with pytest.raises((TypeError, ValueError, BufferError)):
        _rows.columns(src, 4, 0, 2, 0, np.empty(4, np.uint8)[::-1], 1)        # not contiguous
    with pytest.raises((TypeError, ValueError, BufferError)):
        _rows.columns(src, 4, 0, 2, 0, np.frombuffer(b"abcd", np.uint8), 1)  # read-only

"""Invariants of ``lcpcli convert`` at the boundary (README "Problem files", docs/files.md):
every valid problem (LCP, MLCP, box LCP with infinite bounds; dense or sparse M; n = 0 and 1;
entries at ``2^+-1000``, subnormal, ``-0.0``, the largest double; names, descriptions and meta)
converts between JSON, NPZ, HDF5 and Siconos ``.dat`` (stdin and stdout as ``-``) bit for bit:
every array equal byte for byte (``-0.0`` included), ``n_eq``, name, description and meta
equal, except what the README says ``.dat`` cannot hold (the name, description and meta; box
LCPs are refused with one line, exit 2).  Invalid inputs are one line, exit 2, and no output
file; the output is never the input.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from invariants import Case, cases, cli, one_line_error

import lcpcli
from lcpcli.io import load, save
from lcpcli.io.json_format import read_text

SETTINGS = settings(max_examples=100, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])
#: Values at the ends of the double range, planted among the generated data.
EXTREMES = (0.0, -0.0, 5e-324, -5e-324, 2.0 ** -1000, -(2.0 ** 1000), 2.0 ** 1000,
            1.7976931348623157e308, -2.2250738585072014e-308, 1.0 / 3.0)
FORMATS = ("json", "npz", "h5", "dat", "-")

#: JSON values for ``meta``: what a JSON object holds and reads back as itself (finite
#: floats, -0.0 and subnormals included; integers of 64 bits; any text).
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**63), 2**63 - 1)
    | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner,
                                                                max_size=3),
    max_leaves=8)
#: Names and descriptions HDF5 and NPZ hold (no NUL, no lone surrogate; the refusal of those
#: is tested below).
texts = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"),
                max_size=12)


@st.composite
def problems(draw: st.DrawFn) -> lcpcli.Problem:
    """A valid problem from tests/invariants.py, with extreme values planted in M, q and the
    bounds, M sometimes sparse, and a name, description and meta."""
    case: Case = draw(cases(max_n=5))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    M, q = case.M.copy(), case.q.copy()
    kw: dict[str, Any] = case.kwargs()
    if case.n and draw(st.booleans()):
        pick = rng.random(M.shape) < 0.3
        M[pick] = rng.choice(EXTREMES, int(pick.sum()))
        pick = rng.random(case.n) < 0.3
        q[pick] = rng.choice(EXTREMES, int(pick.sum()))
        if case.kind == "box":
            lo = np.where(rng.random(case.n) < 0.3, -0.0, kw["lower"])
            kw["lower"] = np.minimum(lo, kw["upper"])
    if draw(st.booleans()):
        import scipy.sparse as sp

        M = sp.csr_matrix(M)
    return lcpcli.Problem.create(M, q, **kw, name=draw(texts), description=draw(texts),
                                 meta=draw(st.dictionaries(st.text(max_size=5), json_values,
                                                           max_size=3)))


def same_bits(a: Any, b: Any) -> bool:
    """Arrays equal byte for byte (``-0.0`` is not ``0.0``), of the same shape and type."""
    if a is None or b is None:
        return a is None and b is None
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def dense(M: Any) -> np.ndarray:
    """A dense copy by assignment (``toarray`` adds to zeros: ``-0.0`` became ``0.0``)."""
    if not hasattr(M, "tocoo"):
        return M
    coo = M.tocoo()
    out = np.zeros(coo.shape)
    out[coo.row, coo.col] = coo.data
    return out


def same_matrix(a: Any, b: Any) -> bool:
    if hasattr(a, "tocsr") and hasattr(b, "tocsr"):
        return all(same_bits(getattr(a, k), getattr(b, k)) for k in ("data", "indptr")) and \
            np.array_equal(a.indices, b.indices) and a.shape == b.shape
    return same_bits(dense(a), dense(b))


def write_input(p: lcpcli.Problem, folder: Path, fmt: str) -> tuple[str, str | None]:
    if fmt == "-":
        from lcpcli.io.json_format import dumps

        return "-", dumps(p)
    path = folder / f"in.{fmt}"
    save(p, path)
    return str(path), None


def read_output(target: str, out: str) -> lcpcli.Problem:
    if target == "-":
        assert out.endswith("\n") and out.count("\n") == 1, out[-200:]
        return read_text(out, default_name="")
    return load(target)


def assert_same_problem(p: lcpcli.Problem, r: lcpcli.Problem, src: str, dst: str) -> None:
    assert same_matrix(p.M, r.M), (p.M, r.M)
    assert same_bits(p.q, r.q), (p.q, r.q)
    assert same_bits(p.lower, r.lower) and same_bits(p.upper, r.upper), (p.lower, r.lower,
                                                                          p.upper, r.upper)
    assert r.n_eq == p.n_eq and r.kind == p.kind
    if "dat" in (src, dst):  # README: .dat holds M, q and n_eq only
        return
    if p.name:  # a problem without a name is named after its file when read
        assert r.name == p.name
    assert r.description == p.description
    assert json.dumps(r.meta) == json.dumps(p.meta)


@SETTINGS
@example(p=lcpcli.Problem.create(np.zeros((0, 0)), np.zeros(0)), src="json", dst="dat")
@example(p=lcpcli.Problem.create([[-0.0, 5e-324], [2.0 ** 1000, -(2.0 ** -1000)]],
                                 [-0.0, 1.7976931348623157e308], lower=[-np.inf, -0.0],
                                 upper=[0.0, np.inf], name="x"), src="-", dst="h5")
@given(p=problems(), src=st.sampled_from(FORMATS), dst=st.sampled_from(FORMATS))
def test_convert_round_trips_bit_for_bit(tmp_path: Path, p: lcpcli.Problem, src: str,
                                         dst: str) -> None:
    folder = tmp_path / str(np.random.default_rng().integers(1 << 40))
    folder.mkdir()
    if p.kind == "box" and src == "dat":
        src = "json"
    source, stdin = write_input(p, folder, src)
    target = "-" if dst == "-" else str(folder / f"out.{dst}")
    code, out, err = cli("convert", source, target, stdin=stdin)
    if dst == "dat" and p.kind == "box":  # the format has no box LCPs
        one_line_error(code, err)
        assert "box" in err and not Path(target).exists()
        return
    assert code == 0, err
    assert err == "" and (out == "" or target == "-"), (out, err)
    assert_same_problem(p, read_output(target, out), src, dst)


# -------------------------------------------------------------- what a format cannot hold
@pytest.mark.parametrize("field,value", [
    ("name", "a\x00b"), ("description", "d\x00"), ("name", "a\udc80b"),
    ("name", "x" * (2**20 + 1)), ("description", "\u00e9" * (2**19 + 1)),
])
@pytest.mark.parametrize("dst", ["npz", "h5"])
def test_convert_refuses_names_the_format_cannot_hold(tmp_path: Path, field: str, value: str,
                                                      dst: str) -> None:
    """A JSON problem may name itself with any text; NPZ and HDF5 hold names and descriptions
    of at most 1 MiB of UTF-8 without NUL (HDF5: exit 3 on a NUL or a lone surrogate; both
    wrote names over 1 MiB that they then refused to read): the name is kept exactly, or the
    conversion is refused with one line, exit 2, and no file."""
    src = tmp_path / "p.json"
    src.write_text(json.dumps({"M": [[1.0]], "q": [-1.0], field: value}))
    target = tmp_path / f"p.{dst}"
    code, out, err = cli("convert", src, target)
    if code == 0:
        assert getattr(load(target), field) == value
        return
    one_line_error(code, err)
    assert field in err and not target.exists(), err


# ---------------------------------------------------------------------------- invalid input
@SETTINGS
@given(case=cases(max_n=4, kinds=("lcp",)), data=st.data())
def test_convert_invalid_input_one_line_no_output(tmp_path: Path, case: Case,
                                                  data: st.DataObject) -> None:
    """NaN or Inf in the data, a wrong shape, text, n_eq out of range, lower > upper, a
    damaged NPZ/HDF5/.dat file, an unknown extension: exit 2, one line, no output file."""
    folder = tmp_path / str(np.random.default_rng().integers(1 << 40))
    folder.mkdir()
    doc = json.loads(case.to_json())
    n = case.n
    how = data.draw(st.sampled_from(["nan_M", "inf_q", "q_short", "text", "n_eq", "box",
                                     "npz_cut", "h5_cut", "dat_cut", "unknown_ext"]))
    src = folder / "in.json"
    if how == "nan_M":
        doc["M"] = [[float("nan")]] if not n else doc["M"]
        doc["M"][0][0] = float("nan")
        doc["q"] = doc["q"] or [1.0]
    elif how == "inf_q":
        doc["q"] = (doc["q"] or [])[:-1] + [float("-inf")]
        doc["M"] = doc["M"] or [[1.0]]
    elif how == "q_short":
        doc["q"] = doc["q"][:-1] if n else [1.0]
    elif how == "text":
        doc["M"] = "1 2 3"
    elif how == "n_eq":
        doc["n_eq"] = n + 1
    elif how == "box":
        doc["lower"], doc["upper"] = [1.0] * max(n, 1), [0.0] * max(n, 1)
        if not n:
            doc["M"], doc["q"] = [[1.0]], [1.0]
    src.write_text(json.dumps(doc))
    if how.endswith("_cut"):  # a valid file of that format cut short
        good = folder / f"good.{how[:-4]}"
        save(lcpcli.Problem.create(np.ones((3, 3)), np.ones(3)), good)
        src = folder / f"in.{how[:-4]}"
        raw = good.read_bytes()
        # .dat is text: a cut inside its last number leaves a valid (shorter) number
        end = len(raw.rstrip()) - len(raw.rstrip().split()[-1]) if how == "dat_cut" else len(raw)
        src.write_bytes(raw[:data.draw(st.integers(0, end - 1))])
    elif how == "unknown_ext":
        src = src.rename(folder / "in.txt")
    dst = folder / f"out.{data.draw(st.sampled_from(['json', 'npz', 'h5', 'dat']))}"
    code, out, err = cli("convert", src, dst)
    one_line_error(code, err)
    assert out == "" and not dst.exists()
    assert sorted(os.listdir(folder)) == sorted(
        x for x in os.listdir(folder) if not x.startswith(".")), "a temporary file was left"


@pytest.mark.parametrize("ext", ["json", "npz", "h5", "dat"])
def test_convert_output_is_never_the_input(tmp_path: Path, ext: str) -> None:
    """The same path, another spelling, a hard link, with or without --force: one line, exit
    2, the input unchanged byte for byte."""
    src = tmp_path / f"p.{ext}"
    save(lcpcli.Problem.create([[2.0, -0.0], [1.0, 5e-324]], [-1.0, 2.0 ** -1000]), src)
    before = src.read_bytes()
    os.link(src, tmp_path / f"hard.{ext}")
    for target in (src, tmp_path / "." / f"p.{ext}", tmp_path / f"hard.{ext}"):
        for force in ([], ["--force"]):
            code, out, err = cli("convert", src, target, *force)
            one_line_error(code, err)
            assert src.read_bytes() == before

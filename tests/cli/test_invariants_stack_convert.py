"""Invariants of ``lcpcli convert --stack`` and back (docs/batch.md, "Stacked files"): any set of
valid dense problems of one size, one ``n_eq`` and all with bounds or none (K >= 1, n = 0 and 1
included; entries at ``2^+-1000``, subnormal, ``-0.0``, the largest double) stacks from a
folder or a multi-group HDF5 file into ``.h5`` or ``.npz``, copies from stack to stack, and
unstacks to one group per problem or one file per problem, every problem's M, q, bounds and
``n_eq`` equal bit for bit to the original's and its name kept (docs: descriptions and meta are
not stored).  Problems that do not stack (another size, another ``n_eq``, bounds on some only)
are one line, exit 2, and no output.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from invariants import Case, cases, cli, one_line_error

import lcpcli
from lcpcli.io import load, save
from lcpcli.io.hdf5_format import write_many

SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])
EXTREMES = (0.0, -0.0, 5e-324, -5e-324, 2.0 ** -1000, -(2.0 ** 1000), 2.0 ** 1000,
            1.7976931348623157e308, 1.0 / 3.0)


def same_bits(a: object, b: object) -> bool:
    """Arrays equal byte for byte (``-0.0`` is not ``0.0``), of the same shape; a missing
    bound array and an absent one alike."""
    if a is None or b is None:
        return a is None and b is None
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


@st.composite
def stackable(draw: st.DrawFn) -> list[lcpcli.Problem]:
    """K problems of one size, kind and ``n_eq``, with extremes planted and distinct names."""
    first: Case = draw(cases(max_n=4))
    K = draw(st.integers(1, 4))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    out = []
    for k in range(K):
        M, q = first.M.copy(), first.q.copy()
        if k:  # the others: the first's structure with other values (the same kind)
            M = M * rng.choice([1.0, -1.0, 0.5, 2.0], M.shape)
            q = q * rng.choice([1.0, -1.0, 0.5, 2.0], q.shape)
        if first.n and draw(st.booleans()):
            pick = rng.random(M.shape) < 0.3
            M[pick] = rng.choice(EXTREMES, int(pick.sum()))
            pick = rng.random(first.n) < 0.3
            q[pick] = rng.choice(EXTREMES, int(pick.sum()))
        out.append(lcpcli.Problem.create(M, q, **first.kwargs(), name=f"p{k:02d}"))
    return out


def assert_same(orig: list[lcpcli.Problem], back: list[lcpcli.Problem]) -> None:
    assert [p.name for p in back] == [p.name for p in orig]
    for p, r in zip(orig, back, strict=True):
        assert same_bits(p.dense_M(), r.dense_M()), (p.M, r.M)
        assert same_bits(p.q, r.q), (p.q, r.q)
        assert same_bits(p.lower, r.lower) and same_bits(p.upper, r.upper), \
            (p.lower, r.lower, p.upper, r.upper)
        assert r.n_eq == p.n_eq and r.kind == p.kind


def unique(tmp_path: Path) -> Path:
    folder = tmp_path / str(np.random.default_rng().integers(1 << 40))
    folder.mkdir()
    return folder


@SETTINGS
@given(problems=stackable(), src=st.sampled_from(["folder_json", "folder_npz", "groups"]),
       fmt=st.sampled_from(["h5", "npz"]), other=st.sampled_from(["h5", "npz"]),
       back=st.sampled_from(["groups", "json", "npz", "h5"]))
def test_stack_copy_and_unstack_bit_for_bit(tmp_path: Path, problems: list[lcpcli.Problem],
                                            src: str, fmt: str, other: str,
                                            back: str) -> None:
    folder = unique(tmp_path)
    if src == "groups":
        source = folder / "in.h5"
        write_many(problems, source)
    else:
        source = folder / "in"
        source.mkdir()
        for p in problems:
            save(p, source / f"{p.name}.{src.split('_')[1]}")
    stack = folder / f"s.{fmt}"
    code, out, err = cli("convert", source, stack, "--stack")
    if problems[0].n == 0:  # docs/batch.md: a stack holds problems of size n >= 1
        one_line_error(code, err)
        assert "n >= 1" in err and not stack.exists()
        return
    assert code == 0 and out == "" and err == "", err
    copy = folder / f"copy.{other}"
    code, out, err = cli("convert", stack, copy, "--stack")
    assert code == 0 and err == "", err
    if back == "groups":
        target = folder / "back.h5"
        code, out, err = cli("convert", copy, target)
        assert code == 0 and err == "", err
        read = [load(target, p.name) for p in problems]
    else:
        target = folder / "back"
        code, out, err = cli("convert", copy, target, "--format", back)
        assert code == 0 and err == "", err
        assert sorted(os.listdir(target)) == sorted(f"{p.name}.{back}" for p in problems)
        read = [load(target / f"{p.name}.{back}") for p in problems]
    for r, p in zip(read, problems, strict=True):  # names from files follow the file stem
        r.name = p.name
    assert_same(problems, read)


@SETTINGS
@given(problems=stackable(), how=st.sampled_from(["size", "n_eq", "bounds"]),
       fmt=st.sampled_from(["h5", "npz"]))
def test_problems_that_do_not_stack_are_one_line_and_no_output(
        tmp_path: Path, problems: list[lcpcli.Problem], how: str, fmt: str) -> None:
    folder = unique(tmp_path)
    source = folder / "in"
    source.mkdir()
    p = problems[0]
    n = p.n
    if how == "size":
        odd = lcpcli.Problem.create(np.eye(n + 1), np.ones(n + 1), name="zz")
    elif how == "n_eq" and n >= 2:
        odd = lcpcli.Problem.create(p.dense_M(), p.q, n_eq=1 if p.n_eq != 1 else 2,
                                    name="zz")
    elif p.kind == "box":  # bounds on some problems only
        odd = lcpcli.Problem.create(p.dense_M(), p.q, name="zz")
    else:
        odd = lcpcli.Problem.create(p.dense_M(), p.q, lower=np.full(n, -1.0),
                                    upper=np.full(n, 1.0), name="zz") if n and p.n_eq == 0 \
            else lcpcli.Problem.create(np.eye(n + 1), np.ones(n + 1), name="zz")
    for q in [*problems, odd]:
        save(q, source / f"{q.name}.json")
    stack = folder / f"s.{fmt}"
    code, out, err = cli("convert", source, stack, "--stack")
    one_line_error(code, err)
    assert out == "" and not stack.exists()
    assert not [x for x in os.listdir(folder) if x.startswith(".")], "a temporary file was left"


def test_a_file_of_one_group_stacks_under_the_group_name(tmp_path: Path) -> None:
    """An HDF5 file of groups is named by its groups whatever their number (the property found
    a file of one group 'p00' stacked as 'in', the file's stem, while ``load`` named it 'p00'
    and a file of two groups kept both names); a problem at the root keeps its stem."""
    p = lcpcli.Problem.create(np.eye(2), -np.ones(2), name="p00")
    write_many([p], tmp_path / "in.h5")
    assert load(tmp_path / "in.h5").name == "p00"
    for target in ("s.h5", "s.npz"):
        code, _out, err = cli("convert", tmp_path / "in.h5", tmp_path / target, "--stack")
        assert code == 0, err
        assert load(tmp_path / target, "p00").name == "p00"
    code, _out, err = cli("convert", tmp_path / "in.h5", tmp_path / "out", "--format", "json")
    assert code == 0 and os.listdir(tmp_path / "out") == ["p00.json"], err
    save(p, tmp_path / "root.h5")  # M and q at the root: the stem names it in a stack
    code, _out, err = cli("convert", tmp_path / "root.h5", tmp_path / "r.h5", "--stack")
    assert code == 0 and load(tmp_path / "r.h5", "root").name == "root", err

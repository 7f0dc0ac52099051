"""The orjson fast paths of :func:`lcpcli.io.files.parse_json` and
:func:`lcpcli.core.numeric.json_text` give what the stdlib gives: the same decoded values (same
types: an integer beyond 64 bits stays an int), the same refusals and messages (duplicate keys
at any depth, integer length), and output text that decodes to the same value."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.core import numeric
from lcpcli.core.errors import ProblemError
from lcpcli.io import files, json_format, load

orjson = pytest.importorskip("orjson")


@pytest.fixture(autouse=True, scope="module")
def _fast_json_loaded() -> Any:
    """orjson loaded, as in a batch worker (a one-liner loads it only for large texts)."""
    before = numeric._orjson
    numeric._orjson = orjson
    yield
    numeric._orjson = before

SAMPLES = Path(__file__).resolve().parents[2] / "samples"


def _stdlib_parse(monkeypatch: pytest.MonkeyPatch, text: str) -> Any:
    with monkeypatch.context() as m:
        m.setattr(numeric, "_orjson", None)
        return files.parse_json(text)


def _same(a: Any, b: Any) -> bool:
    """Equal values of equal types (``1`` and ``1.0`` differ; NaN equals NaN; -0.0 is not 0.0)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float):
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a)
                                                      == math.copysign(1, b))
    return a == b


@pytest.mark.parametrize("path", sorted(SAMPLES.glob("*.json")), ids=lambda p: p.name)
def test_samples_parse_and_load_the_same(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    text = path.read_text(encoding="utf-8")
    assert _same(files.parse_json(text), _stdlib_parse(monkeypatch, text))
    if "M" not in json.loads(text):
        return
    try:
        with monkeypatch.context() as m:
            m.setattr(numeric, "_orjson", None)
            slow = load(path)
    except ProblemError as exc:  # a sample of a refused input: refused the same way
        with pytest.raises(ProblemError) as got:
            load(path)
        assert str(got.value) == str(exc)
        return
    fast = load(path)
    assert fast.name == slow.name and fast.n_eq == slow.n_eq
    for a, b in ((fast.M, slow.M), (fast.q, slow.q)):
        a = a.toarray() if hasattr(a, "toarray") else np.asarray(a)
        b = b.toarray() if hasattr(b, "toarray") else np.asarray(b)
        assert np.array_equal(a, b, equal_nan=True)


def test_sample_problems_take_the_fast_path() -> None:
    """The sample problem files are decoded by orjson, not sent back to the stdlib."""
    problems = [p for p in sorted(SAMPLES.glob("*.json")) if '"M"' in p.read_text("utf-8")]
    assert problems
    for path in problems:
        assert files._fast_parse(path.read_text(encoding="utf-8"))[0], path.name


numbers = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False),
    st.floats(min_value=-1e-300, max_value=1e-300),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.sampled_from([2**63 - 1, 2**63, 2**64 - 1, 2**64, -(2**63), -(2**63) - 1, 5e-324,
                     1.7976931348623157e308, -0.0, 0]))
keys = st.text(st.sampled_from('ab:{"\\ é'), min_size=0, max_size=3)
documents = st.recursive(
    numbers | st.none() | st.booleans() | keys,
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(keys, inner, max_size=4),
    max_leaves=30)


@settings(max_examples=300, deadline=None)
@given(doc=documents, indent=st.sampled_from([None, 1]))
def test_documents_parse_the_same(doc: Any, indent: int | None) -> None:
    text = json.dumps(doc, indent=indent)
    expected = json.loads(text)
    assert _same(files.parse_json(text), expected)
    assert _same(files.parse_json(text.encode()), expected)


@settings(max_examples=200, deadline=None)
@given(doc=st.dictionaries(keys, documents, min_size=1, max_size=4), data=st.data())
def test_duplicate_keys_refused_with_orjson(doc: dict[str, Any], data: st.DataObject) -> None:
    """A key repeated in any object (top level or nested) is refused, as by the stdlib."""
    key = data.draw(st.sampled_from(sorted(doc)))
    inner = json.dumps(doc)[1:-1]
    dup = json.dumps(key) + ": 1"
    for text in ("{" + inner + ", " + dup + "}", '{"x": [{' + inner + ", " + dup + "}]}"):
        with pytest.raises(ProblemError, match="appears twice in one object"):
            files.parse_json(text)


@pytest.mark.parametrize("text", ['{"a": 1, "a": 1}', '[{"a": 1}, {"b": {"c": 2, "c": 3}}]',
                                  '{"M": [[1]], "q": [1], "q": [1]}',
                                  '{"a:": 1, "a": 2, "a": 3}'])
def test_duplicate_keys_refused_fixed(text: str) -> None:
    with pytest.raises(ProblemError, match="appears twice"):
        files.parse_json(text)


@pytest.mark.parametrize("literal", ["1" * 19, "-" + "9" * 19, "1" * 700, "1e400", "-1e400",
                                     "NaN", "Infinity", "[" * 3000 + "]" * 3000,
                                     "[" * 150 + "]" * 150])
def test_long_and_special_numbers_as_stdlib(literal: str,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    text = '{"q": [' + literal + "]}"
    try:
        expected: Any = _stdlib_parse(monkeypatch, text)
    except ProblemError as exc:
        with pytest.raises(ProblemError) as got:
            files.parse_json(text)
        assert str(got.value) == str(exc)
    else:
        assert _same(files.parse_json(text), expected)


def test_problem_with_long_integer_reads_as_before(monkeypatch: pytest.MonkeyPatch) -> None:
    text = '{"M": [[18446744073709551617]], "q": [-1]}'
    fast = json_format.read_text(text)
    with monkeypatch.context() as m:
        m.setattr(numeric, "_orjson", None)
        slow = json_format.read_text(text)
    assert np.array_equal(np.asarray(fast.M), np.asarray(slow.M))


rows = st.recursive(
    st.floats() | st.integers(min_value=-(2**70), max_value=2**70) | st.none() | st.booleans()
    | st.text(max_size=4),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=3), inner,
                                                                max_size=4),
    max_leaves=30)


@settings(max_examples=300, deadline=None)
@given(row=rows)
def test_json_text_means_the_same(row: Any) -> None:
    """Same value as the stdlib text, non-finite numbers as null, ASCII only, no NaN token."""
    fast = numeric.json_text(row)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(numeric, "_orjson", None)
        slow = numeric.json_text(row)
    assert fast.isascii()

    def no_constant(token: str) -> Any:  # a NaN/Infinity token (not a string holding "NaN")
        raise AssertionError(f"non-JSON token {token} in {fast}")

    assert _same(json.loads(fast, parse_constant=no_constant), json.loads(slow))


def test_json_text_numpy_and_nonfinite() -> None:
    row = {"x": np.float64(1.5), "y": [math.inf, -math.inf, math.nan, 1e-5, 1e16], 3: "k"}
    assert json.loads(numeric.json_text(row)) == {"x": 1.5, "y": [None, None, None, 1e-5, 1e16],
                                                  "3": "k"}


def test_a_one_liner_loads_orjson_only_for_a_large_text(monkeypatch: pytest.MonkeyPatch) -> None:
    """Small texts are parsed and written without importing orjson (start-up); a text of
    FAST_JSON_MIN_BYTES or more loads it; a batch worker loads it up front."""
    from lcpcli.batch.worker import prepare_method

    monkeypatch.setattr(numeric, "_orjson", None)
    assert files.parse_json('{"M": [[1]], "q": [1]}') == {"M": [[1]], "q": [1]}
    assert numeric.json_text({"z": [0.5]}) == '{"z": [0.5]}'  # the stdlib's separators
    assert numeric._orjson is None
    big = '{"q": [' + ", ".join(["1.5"] * (numeric.FAST_JSON_MIN_BYTES // 4)) + "]}"
    assert files.parse_json(big)["q"][0] == 1.5
    assert numeric._orjson is orjson
    monkeypatch.setattr(numeric, "_orjson", None)
    prepare_method("lemke")
    assert numeric._orjson is orjson


def _load_both(tmp_path: Path, text: str | bytes) -> tuple[Any, Any]:
    """``load`` of a JSON file with orjson (its bytes parsed undecoded) and with the stdlib:
    each a Problem, or the message of the ProblemError it raised."""
    path = tmp_path / "p.json"
    path.write_bytes(text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text)
    out = []
    for codec in (orjson, None):
        with pytest.MonkeyPatch.context() as m:
            m.setattr(numeric, "_orjson", codec)
            try:
                out.append(load(path))
            except ProblemError as exc:
                out.append(str(exc))
    return out[0], out[1]


def _same_problem(a: Any, b: Any) -> bool:
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    dense = [(x.toarray() if hasattr(x, "toarray") else np.asarray(x)) for x in (a.M, b.M)]
    bounds = [(a.lower, b.lower), (a.upper, b.upper)]
    return (a.name == b.name and a.description == b.description and a.n_eq == b.n_eq
            and _same(a.meta, b.meta) and dense[0].dtype == dense[1].dtype
            and np.array_equal(dense[0], dense[1]) and np.array_equal(a.q, b.q)
            and all((x is None and y is None) or np.array_equal(x, y) for x, y in bounds))


@pytest.mark.parametrize("text", [
    '{"M": [[1]], "q": [1], "q": [2]}',                        # duplicate keys
    '{"M": [[1]], "q": [1], "meta": {"a": 1, "a": 2}}',
    '{"M": [[' + "1" * 401 + ']], "q": [1]}',                 # beyond the digit limit
    '{"M": [[1' + "0" * 350 + ']], "q": [1]}',                # beyond float64
    '{"M": [[' + "9" * 19 + ']], "q": [1]}',
    '{"M": [[1]], "q": [1], "meta": {"k": ' + "7" * 25 + '}}',  # an int kept exactly
    '{"M": [[1]], "q": [1], "n_eq": ' + "1" * 30 + '}',
    '{"M": [[NaN]], "q": [1]}', '{"M": [[1]], "q": [Infinity]}',
    '{"M": [[true]], "q": [1]}', '{"M": [[1.5, false], [1, 2]], "q": [1, 2]}',
    '{"M": [[1, 2], [3, 4]], "q": [true, 1]}',
    '{"M": [["1.5"]], "q": [1]}', '{"M": [[1]], "q": ["1"]}', '{"M": [[null]], "q": [1]}',
    '{"M": [[1, 2], [3]], "q": [1, 2]}', '{"M": [1, 2], "q": [1, 2]}',
    '{"M": [[[1]]], "q": [1]}', '{"M": [[1], "ab"], "q": [1, 2]}', '{"M": [], "q": []}',
    '{"M": [[2, 1], [1, 2]], "q": [-1, -1]}', '{"M": [[2, 1.5], [1, 2]], "q": [-1, -1]}',
    '{"name": "true story", "M": [[1e-300, 2E+5]], "q": [1]}',
    '{"M": [[1]], "q": [1], "lower": [null], "upper": ["inf"]}',
    '{"M": {"format": "csr", "shape": [1, 1], "data": [1], "indices": [0], "indptr": [0, 1]},'
    ' "q": [1]}',
    '\ufeff{"M": [[1]], "q": [1]}', '{"name": "\\ud800", "M": [[1]], "q": [1]}',
    '{"M": [[1]], "q": [1]', '[1, 2]', '1' * 500])
def test_a_file_loads_as_with_the_stdlib(text: str, tmp_path: Path) -> None:
    """A JSON problem file read through orjson (its bytes undecoded, the matrix converted in
    one step) gives the problem the stdlib gives, or refuses it with the same one line:
    duplicate keys, long integers, NaN, booleans, strings, null, ragged rows, a BOM."""
    fast, slow = _load_both(tmp_path, text)
    assert _same_problem(fast, slow), (fast, slow)


def test_a_file_that_is_not_utf8_is_refused_as_before(tmp_path: Path) -> None:
    fast, slow = _load_both(tmp_path, b'{"name": "\xff", "M": [[1]], "q": [1]}')
    assert fast == slow and "UTF-8" in fast


cells = st.one_of(numbers, st.booleans(), st.none(), st.sampled_from(["1.5", "x", "true"]),
                  st.lists(numbers, max_size=2))


@settings(max_examples=300, deadline=None)
@given(M=st.lists(st.one_of(st.lists(cells, min_size=1, max_size=3), cells), min_size=1,
                  max_size=3),
       q=st.lists(cells, min_size=1, max_size=3), name=keys)
def test_any_matrix_loads_as_with_the_stdlib(M: Any, q: Any, name: str) -> None:
    """Matrices of any cells (numbers of every size, booleans, null, strings, nested lists,
    ragged rows): the file gives what the stdlib path gives, problem or message."""
    import tempfile

    text = json.dumps({"name": name, "M": M, "q": q})
    with tempfile.TemporaryDirectory() as tmp:
        fast, slow = _load_both(Path(tmp), text)
    assert _same_problem(fast, slow), (text, fast, slow)

"""One definition per term: statuses and terminations, exit codes, the version."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

import lcpcli
import lcpcli.core.errors as errors
from lcpcli.core.result import STATUSES, Status, Termination

ROOT = Path(__file__).resolve().parents[2]


def test_status_and_termination_enums_read_as_their_strings():
    assert Status.SOLVED == "solved" and Termination.RAY == "ray_termination"
    assert f"{Status.NO_SOLUTION}" == "no_solution" and str(Termination.CONVERGED) == "converged"
    assert f"{Status.UNSOLVED:>10}" == "  unsolved"
    assert json.dumps({Status.SOLVED: Termination.ITERATION_LIMIT}) == \
        '{"solved": "iteration_limit"}'
    assert {"solved": 1}[Status.SOLVED] == 1
    assert STATUSES == (Status.SOLVED, Status.NO_SOLUTION, Status.UNSOLVED)


def test_every_exit_code_is_defined_once_and_documented():
    codes = {name: getattr(errors, name) for name in dir(errors) if name.startswith("EXIT_")}
    assert codes["EXIT_SOLVED"] == codes["EXIT_OK"] == 0
    assert (codes["EXIT_NOT_SOLVED"], codes["EXIT_BAD_INPUT"], codes["EXIT_INTERNAL"],
            codes["EXIT_HANGUP"], codes["EXIT_INTERRUPTED"],
            codes["EXIT_TERMINATED"]) == (1, 2, 3, 129, 130, 143)
    # a signal's exit code is 128 + its number, as a shell reports a process it killed
    assert all(code == 128 + sig for sig, code in errors.STOP_SIGNALS.items())
    assert set(errors.STOP_SIGNALS.values()) == {129, 130, 143}
    readme = (ROOT / "README.md").read_text()
    assert "| 129 / 130 / 143 |" in readme
    doc = errors.__doc__ or ""
    for value in set(codes.values()):
        assert re.search(rf"\b{value}\b", doc), value
    # no other module assigns an EXIT_ constant
    for path in (ROOT / "lcpcli").rglob("*.py"):
        if path.name == "errors.py" and path.parent.name == "core":
            continue
        assert not re.search(r"^EXIT_[A-Z_]+\s*=\s*\d", path.read_text(), re.M), path


def test_the_version_is_defined_once():
    text = (ROOT / "pyproject.toml").read_text()
    assert not re.search(r"^version\s*=\s*\"", text, re.M)  # no literal version string
    assert re.search(r'^dynamic = \["version"\]', text, re.M)
    assert re.search(r'^version = \{ attr = "lcpcli.__version__" \}', text, re.M)
    assert re.fullmatch(r"\d+\.\d+\.\d+", lcpcli.__version__)


def test_plural_words_and_thousands():
    from lcpcli.core.text import plural

    assert plural(1, "pivot") == "1 pivot"
    assert plural(0, "problem") == "0 problems"
    assert plural(999, "pivot") == "999 pivots"
    assert plural(1000, "pivot") == "1,000 pivots"
    assert plural(-1500, "step") == "-1,500 steps"
    assert plural(np.int64(1234567), "cone") == "1,234,567 cones"
    assert plural(2, "matrix", "matrices") == "2 matrices"


def test_result_rows_map_non_finite_numbers_to_null():
    import dataclasses

    from lcpcli.core.certificate import Certificate
    from lcpcli.core.result import _floats

    assert _floats(np.array([1.5, np.inf, -np.inf, np.nan, 0.0])) == [1.5, None, None, None, 0.0]
    assert _floats(np.arange(3)) == [0.0, 1.0, 2.0]
    assert all(type(x) is float for x in _floats(np.ones(4, dtype=np.float32)))
    big = np.array([1e308, 1e308, -0.0, 5e-324])  # the sum overflows: still all finite
    assert _floats(big) == [1e308, 1e308, -0.0, 5e-324]
    assert _floats(np.array([np.inf, -np.inf, 1.0])) == [None, None, 1.0]  # inf - inf = nan
    from lcpcli.core.result import BASIS_LETTERS, basis_text

    rng = np.random.default_rng(3)
    for dtype in (np.int8, np.uint8, np.int16, np.int64):
        for shape in ((0,), (7,), (3, 4)):
            codes = rng.integers(0, 3, shape).astype(dtype)
            want = "".join(BASIS_LETTERS[c] for c in codes.ravel().tolist())
            assert basis_text(codes) == want
            assert basis_text(codes[..., ::2]) == "".join(
                BASIS_LETTERS[c] for c in codes[..., ::2].ravel().tolist())
    assert basis_text(np.array([0, -1, 2], np.int8)) == "LFF"  # numpy's index wraps, as before
    with pytest.raises(IndexError):
        basis_text(np.array([0, 3], np.int8))
    for _ in range(200):
        v = rng.choice([0.0, -0.0, 1.5, -2e308 / 2, 1e308, np.inf, -np.inf, np.nan],
                       size=rng.integers(0, 6))
        assert _floats(v) == [float(x) if np.isfinite(x) else None for x in v]
    c = Certificate(1e-17, 1e-17, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1, 1e-8, True)
    assert c.as_dict() == dataclasses.asdict(c)
    assert list(c.as_dict()) == [f.name for f in dataclasses.fields(c)]


def _sources() -> list[tuple[Path, str]]:
    return [(p, p.read_text()) for p in sorted((ROOT / "lcpcli").rglob("*.py"))
            + sorted((ROOT / "lcpcli").rglob("*.pyx"))]


def _definers(pattern: str) -> list[str]:
    """The package modules (relative paths) that match ``pattern`` (multi-line)."""
    return [str(p.relative_to(ROOT)) for p, text in _sources() if re.search(pattern, text, re.M)]


def test_every_tolerance_of_core_tolerances_is_defined_there_only():
    import lcpcli.core.tolerances as tolerances

    names = [n for n in vars(tolerances) if n.isupper()]
    assert {"PIVOT_TOL", "TIE_TOL", "POLISHED", "P_TEST_PIVOT_TOL"} <= set(names)
    for name in names:
        assert _definers(rf"^{name}\s*[:=]") == ["lcpcli/core/tolerances.py"], name
        assert "#: " in (ROOT / "lcpcli/core/tolerances.py").read_text().split(f"\n{name}")[0]


@pytest.mark.parametrize("pattern, home", [
    (r"^def diagonal\(", "lcpcli/analysis/classify.py"),
    (r"^def is_symmetric\(", "lcpcli/analysis/classify.py"),
    # Lemke's default pivot limit: in the kernel module, which applies it to a limit of 0
    # (lcpcli.solvers.methods.lemke re-exports its Python face, default_max_iter)
    (r"^cdef int64_t default_pivot_limit\(int64_t n\) noexcept nogil:\n(.*\n)*?"
     r"\s+return 100 \* n if 100 \* n > 1000 else 1000", "lcpcli/solvers/kernels/lemke.pyx"),
    (r"max\(1000, 100 \* n\)|100 \* n if 100 \* n > 1000", "lcpcli/solvers/kernels/lemke.pyx"),
    (r"return max\(50, n\)|n if n > 50 else 50", "lcpcli/solvers/kernels/lemke_revised.pyx"),
    (r"^DEFAULT_METHOD\s*=", "lcpcli/solvers/__init__.py"),
    (r"^def option_name\(", "lcpcli/core/text.py"),
    (r"^MAX_ITER\s*=\s*2\s*\*\*", "lcpcli/core/limits.py"),
])
def test_each_shared_term_has_one_definition(pattern, home):
    assert _definers(pattern) == [home]


def test_option_names_and_the_default_method_are_used_not_respelled():
    # no module spells the normalisation or the default method out again
    assert _definers(r'\.replace\("-", "_"\)') == ["lcpcli/core/text.py"]
    assert _definers(r'typer\.Option\("auto", "--method"') == []
    assert _definers(r'method: str = "auto"') == []
    from lcpcli.core.text import option_name
    from lcpcli.solvers import DEFAULT_METHOD
    from lcpcli.solvers.registry import get_method

    assert option_name("max-iter") == "max_iter" and option_name("omega") == "omega"
    assert get_method(DEFAULT_METHOD).planner
    assert get_method("lemke").parse_options({"max-iter": 7})["max_iter"] == 7

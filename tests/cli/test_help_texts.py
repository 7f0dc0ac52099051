"""Help texts and messages say what the commands do (defaults, accepted values, suffixes)."""

from __future__ import annotations

import json
import re

from lcpcli.batch.output import _KINDS

WIDE = {"COLUMNS": "300", "NO_COLOR": "1", "TERM": "dumb"}


def _option_help(cli, command: str, option: str) -> str:
    """The help paragraph of ``option`` in ``lcpcli COMMAND --help``, on one line."""
    r = cli(command, "--help", env=WIDE)
    assert r.returncode == 0, r.stderr
    text = re.sub(r"[\s│|]+", " ", r.stdout)
    start = text.index(option + " ", text.index("Options"))
    following = re.search(r" --?[a-z][a-z-]* ", text[start + len(option) + 1:])
    return text[start: start + len(option) + 1 + (following.start() if following else 400)]


def test_contact_friction_help_gives_the_rule_and_its_default_once(cli, samples):
    text = _option_help(cli, "contact-matrix", "--friction")
    assert text.count("default") == 1 and "[default: 0, frictionless]" in text
    assert "3-D K >= 3" in text and "2-D K >= 2" in text
    # the help's rule, checked on a planar 3-D scene: K = 2 refused, K = 3 accepted (reduced)
    planar = str(samples / "scene_planar_3d.json")
    assert cli("contact-matrix", planar, "--friction", "2").returncode == 2
    assert cli("contact-matrix", planar, "--friction", "3").returncode == 0
    assert cli("contact-matrix", str(samples / "scene_2d_boxes.json"),
               "--friction", "3").returncode == 0


def test_solve_tol_help_names_the_default_every_method_has(cli):
    methods = json.loads(cli("methods", "--json").stdout)
    tols = {m["default_tol"] for m in methods}
    assert tols == {1e-8}
    text = _option_help(cli, "solve", "--tol")
    assert "[default: 1e-8, every method's default_tol]" in text


def test_unknown_result_suffix_lists_every_accepted_one(cli, samples, tmp_path):
    r = cli("solve", str(samples / "seed000.json"), str(samples / "seed004.json"),
            "--output", str(tmp_path / "r.hdf"))
    assert r.returncode == 2
    for ext in _KINDS:
        assert ext in r.stderr, (ext, r.stderr)
    for ext in (".ndjson", ".hdf5"):  # accepted, as the message says
        out = tmp_path / f"r{ext}"
        r = cli("solve", str(samples / "seed000.json"), str(samples / "seed004.json"),
                "--output", str(out))
        assert r.returncode == 0 and out.exists(), r.stderr

"""Project hygiene: CI runs exactly the README's commands."""

from __future__ import annotations


def test_ci_runs_the_readme_commands(root):
    readme = (root / "README.md").read_text()
    block = readme.split("## Set-up: two commands", 1)[1].split("```bash", 1)[1].split("```")[0]
    commands = [line.strip() for line in block.strip().splitlines()]
    ci = [line.strip() for line in (root / ".ci" / "run").read_text().splitlines()
          if line.strip() and not line.startswith("#")]
    assert len(commands) == 2
    for command in commands:
        assert command in ci

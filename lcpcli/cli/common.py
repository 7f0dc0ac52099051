"""Helpers shared by the subcommands: option parsing, consoles, exit codes, method help."""

from __future__ import annotations

import json
import sys
from typing import Any

import typer.core

from lcpcli.core.errors import EXIT_BAD_INPUT, EXIT_NOT_SOLVED, EXIT_SOLVED, OptionError


class MethodListCommand(typer.core.TyperCommand):
    """A command whose ``--help`` ends with the registered solver methods (built lazily)."""

    def format_epilog(self, ctx: Any, formatter: Any) -> None:
        from lcpcli.solvers.registry import methods

        rows = []
        for name, m in methods().items():
            alias = f" (alias: {', '.join(m.aliases)})" if m.aliases else ""
            kinds = "/".join(k.upper() for k in m.kinds)
            rows.append((name + alias, f"{m.summary}. Classes: {m.matrix_classes}. "
                                       f"Problems: {kinds}."))
        with formatter.section("Methods"):
            formatter.write_dl(rows)
        super().format_epilog(ctx, formatter)


def parse_key_values(pairs: list[str] | None) -> dict[str, str]:
    """``["omega=1.2", "max-iter=50"]`` -> ``{"omega": "1.2", "max_iter": "50"}``."""
    out: dict[str, str] = {}
    for item in pairs or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise OptionError(f"method option must look like KEY=VALUE, got {item!r}")
        out[key.strip().replace("-", "_")] = value.strip()
    return out


def stdout_console() -> Any:
    """A rich console on stdout (colour only on a TTY and never with NO_COLOR)."""
    from rich.console import Console

    return Console(highlight=False)


def stderr_console() -> Any:
    from rich.console import Console

    return Console(stderr=True, highlight=False)


def exit_code_for(statuses: list[str]) -> int:
    """0 if every status is ``solved``, 1 otherwise (bad input is raised, not returned)."""
    from lcpcli.core.result import Status  # imports numpy: not at --help time

    return EXIT_SOLVED if all(s == Status.SOLVED for s in statuses) else EXIT_NOT_SOLVED


def write_json_line(obj: Any) -> None:
    """One JSON object on stdout (nothing else goes there with ``--json``)."""
    sys.stdout.write(json.dumps(obj, allow_nan=False) + "\n")
    sys.stdout.flush()


__all__ = ["EXIT_BAD_INPUT", "MethodListCommand", "exit_code_for", "parse_key_values",
           "stderr_console", "stdout_console", "write_json_line"]

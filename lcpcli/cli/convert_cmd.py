"""``lcpcli convert``: rewrite a problem file in another format."""

from __future__ import annotations

from pathlib import Path

import typer

from lcpcli.core.errors import EXIT_OK


def convert(
    source: str = typer.Argument(..., metavar="IN", help="Problem file ('-' = JSON on stdin)."),
    target: str = typer.Argument(..., metavar="OUT",
                                 help="Output file; the extension picks the format "
                                      "(.json, .npz, .h5, .dat); '-' writes JSON to stdout."),
    problem: str = typer.Option(None, "--problem", "-p",
                                help="Problem (group) of an HDF5 input; without it every "
                                     "problem of a multi-problem file goes to an HDF5 OUT."),
    force: bool = typer.Option(False, "--force", "-f", help="Overwrite an existing OUT."),
) -> int:
    """Convert between JSON, NPZ, HDF5 and Siconos .dat problem files.

    The output is written atomically and only after the input was read and validated, so a
    bad input never leaves a partial or damaged OUT. OUT is never the input file (compared by
    inode), a symbolic link, a directory or a device, whatever --force says. Exit codes: 0
    done; 2 bad usage or bad input.
    """
    from lcpcli.core.errors import ProblemError
    from lcpcli.io import atomic_path, check_output, detect_format, list_problems, load, save

    out_fmt = detect_format(target)
    # before reading anything: OUT is never IN (by inode), a link, a device or a directory
    check_output(target, inputs=[source], force=force)
    in_fmt = detect_format(source)
    if in_fmt == "hdf5" and problem is None and source != "-":
        names = list_problems(source)
        if len(names) > 1:
            if out_fmt != "hdf5":
                raise ProblemError(f"holds {len(names)} problems ({', '.join(names[:20])}); "
                                   f"pick one with --problem NAME or convert to .h5", source)
            from lcpcli.io.hdf5_format import write_many

            problems = [load(source, name) for name in names]
            for name, p in zip(names, problems, strict=True):
                p.name = name
            with atomic_path(Path(target)) as tmp:
                write_many(problems, tmp)
            return EXIT_OK
    save(load(source, problem), target)
    return EXIT_OK


def register(app: typer.Typer) -> None:
    app.command("convert")(convert)

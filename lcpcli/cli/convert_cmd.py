"""``lcpcli convert``: rewrite a problem file in another format, stack problems, unstack them."""

from __future__ import annotations

from pathlib import Path

import typer

from lcpcli.core.errors import EXIT_OK, ProblemError


def convert(
    source: str = typer.Argument(..., metavar="IN",
                                 help="Problem file ('-' = JSON on stdin); with --stack also a "
                                      "folder of problem files."),
    target: str = typer.Argument(..., metavar="OUT",
                                 help="Output file; the extension picks the format "
                                      "(.json, .npz, .h5, .dat); '-' writes JSON to stdout. "
                                      "With --format: a folder."),
    problem: str = typer.Option(None, "--problem", "-p",
                                help="Problem (group) of an HDF5 input; without it every "
                                     "problem of a multi-problem file goes to an HDF5 OUT."),
    stack: bool = typer.Option(False, "--stack",
                               help="Write every problem of IN (a folder, a multi-group HDF5 "
                                    "file, a stacked file) as one stacked file OUT (.h5 or "
                                    ".npz): dense problems of one size."),
    fmt: str = typer.Option(None, "--format", metavar="FMT",
                            help="OUT is a folder (created if missing): one FMT file per "
                                 "problem (json, npz, h5, dat), named after the problem."),
    force: bool = typer.Option(False, "--force", "-f",
                               help="Overwrite an existing OUT (with --format: existing files "
                                    "in the folder)."),
) -> int:
    """Convert between JSON, NPZ, HDF5 and Siconos .dat problem files; stack and unstack.

    A stacked file (.h5/.npz: M of shape (K, n, n), q (K, n); see docs/batch.md) is made with
    --stack from a folder, a multi-group HDF5 file or another stack; a stack given to an .h5
    OUT becomes one group per problem, and with --format one file per problem in a folder.
    The output is written atomically and only after the input was read and validated, so a
    bad input never leaves a partial or damaged OUT. OUT is never the input file (compared by
    inode), a symbolic link, a directory or a device, whatever --force says. Exit codes: 0
    done; 2 bad usage or bad input.
    """
    from lcpcli.io import (
        PROBLEM_EXTENSIONS,
        atomic_path,
        check_output,
        detect_format,
        input_format,
        list_problems,
        load,
        save,
    )
    from lcpcli.io import stack as stacked

    src_dir = source != "-" and Path(source).is_dir()
    if fmt is not None:  # OUT is a folder
        if stack:
            raise ProblemError("--stack writes one file and --format a folder of files; give "
                               "one of them")
        if problem is not None:
            raise ProblemError("--problem picks one problem; --format writes every problem")
        if target != "-":
            stacked.check_output_folder(target)
            stacked.write_folder(source, target, fmt, force=force)
            return EXIT_OK
        if detect_format("", fmt) != "json":
            raise ProblemError(f"is stdout, which takes JSON only: --format {fmt} writes "
                               f"files into a folder; give the folder", "-")
        # '-' with --format json: JSON on stdout, as without --format
    out_fmt = detect_format(target)
    # before reading anything: OUT is never IN (by inode), a link, a device or a directory
    check_output(target, inputs=[source], force=force)
    if stack:
        if problem is not None:
            raise ProblemError("--stack takes every problem of IN; --problem picks one")
        if Path(target).suffix.lower() not in stacked.STACK_FORMATS:
            raise ProblemError("a stacked file is written as .h5/.hdf5/.hdf or .npz", target)
        if src_dir and Path(target).suffix.lower() in PROBLEM_EXTENSIONS \
                and Path(target).resolve().parent == Path(source).resolve():
            raise ProblemError(f"is inside the input folder {source}: it would be read as one "
                               f"of its problems; write it elsewhere", target)
        stacked.write_stack_from(source, target)
        return EXIT_OK
    if src_dir and Path(source).suffix.lower() not in PROBLEM_EXTENSIONS:
        raise ProblemError("is a folder: add --stack to write its problems as one stacked "
                           "file", source)
    try:
        in_fmt = input_format(source)
    except ProblemError as exc:
        raise exc.with_source(source) from None
    if source != "-" and problem is None and in_fmt in ("hdf5", "npz") \
            and stacked.is_stack(source):
        if out_fmt == "hdf5":
            stacked.write_groups(stacked.source_problems(source), target)
            return EXIT_OK
        K = stacked.stack_info(source).K
        if K > 1:
            raise ProblemError(f"holds {K:,} stacked problems: convert them to an .h5 file "
                               f"(one group each), to a folder (OUT --format FMT) or to a "
                               f"stack (--stack)", source)
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
    prob = load(source, problem)
    try:
        save(prob, target)
    except ProblemError as exc:  # what OUT's format cannot hold: the message names OUT
        raise exc.with_source(target) from None
    return EXIT_OK


def register(app: typer.Typer) -> None:
    app.command("convert")(convert)

"""The ``legbench`` command. The only place that catches :class:`LegbenchError`.

One convention for every subcommand: a registrar ``(subparsers) -> None``
adds the subcommand's parser and sets ``func``, its handler, which takes the
parsed arguments and returns the exit status. :data:`COMMANDS` maps each
subcommand, in help order, to its registrar (``module:function``): the core
commands in :mod:`legbench.commands`, each study in its own module of
:mod:`legbench.studies`.

Start-up is kept light: the signal handlers are installed before anything
slow is imported, and only the module of the subcommand asked for is imported
(``legbench --help`` lists them from :data:`SUMMARY`, importing none).

Global options: ``--version``; ``--model PATH``, another leg parameter file for this command
(also ``LEGBENCH_MODEL``, see :mod:`legbench.resources`). Shell completion comes from argcomplete:
``eval "$(legbench completion bash)"`` (or ``zsh``, ``fish``, ``tcsh``).
"""
# PYTHON_ARGCOMPLETE_OK

from __future__ import annotations

import argparse
import gc
import importlib
import os
import re
import select
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from types import CodeType
from typing import Any, NoReturn

from legbench import __version__, resources
from legbench.exceptions import LegbenchError, ModelError
from legbench.exitcodes import EXIT_INTERRUPTED, EXIT_IO_ERROR, EXIT_OUTPUT_CLOSED, EXIT_USER_ERROR

#: subcommand -> registrar ``module:function``, in help order.
COMMANDS: dict[str, str] = {
    "model": "legbench.commands:add_model",
    "run": "legbench.commands:add_run",
    "validate": "legbench.commands:add_validate",
    "schema": "legbench.commands:add_schema",
    "compare": "legbench.commands:add_compare",
    "check": "legbench.commands:add_check",
    "backends": "legbench.commands:add_backends",
    "doctor": "legbench.studies.doctor:add_cli",
    "sweep": "legbench.studies.sweep:add_cli",
    "verify": "legbench.studies.verify:add_cli",
    "calibrate-contact": "legbench.studies.calibrate_contact:add_cli",
    "bench": "legbench.studies.bench:add_cli",
    "reproduce": "legbench.studies.reproduce:add_cli",
    "completion": "legbench.cli:add_completion",
}
#: subcommand -> its one-line help, for ``legbench --help`` without importing every subcommand's module
#: (the same text as each registrar's ``help=``; tests/test_cli.py keeps them equal).
SUMMARY: dict[str, str] = {
    "model": "the leg model: kinematics, gravity, URDF generation",
    "run": "run scenarios on one or more backends, then compare them",
    "validate": "check scenario, sweep, tolerance, framework and leg parameter files without running them",
    "schema": "print the JSON Schema of the scenario format (for editors)",
    "compare": "compare the backends of a run directory (or a tree of them) and report",
    "check": "regression check of new results against a committed baseline",
    "backends": "the backends legbench finds: what runs here, and how to install the rest",
    "doctor": "parity pre-flight: what each engine holds, read back, side by side",
    "sweep": "run a parameter sweep (grid over scenario and backend settings)",
    "verify": "verification cases with closed-form answers, on every backend",
    "calibrate-contact": "effective contact stiffness, damping and creep per backend",
    "bench": "time the full run against the engine alone (CPU time), per backend and task",
    "reproduce": "the lab report's comparison in one command: its tables from the framework analogues",
    "completion": 'print shell code for tab completion: eval "$(legbench completion bash)"',
}
#: Global options that take a value (skipped when looking for the subcommand's name).
_VALUED = ("--model",)


def _first_command(argv: Sequence[str]) -> str | None:
    """The first positional word of ``argv``, skipping global options and their values."""
    skip = False
    for a in argv:
        if skip:
            skip = False
        elif a in _VALUED:
            skip = True
        elif not a.startswith("-"):
            return a
    return None


def _completion(args: argparse.Namespace) -> int:
    import argcomplete

    sys.stdout.write(argcomplete.shellcode(["legbench"], shell=args.shell))
    return 0


def add_completion(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """``legbench completion SHELL``: the shell code that enables tab completion (argcomplete)."""
    p = sub.add_parser(
        "completion",
        help='print shell code for tab completion: eval "$(legbench completion bash)"',
        description="Print the code that enables tab completion of legbench commands and options in SHELL "
        '(argcomplete). bash: add `eval "$(legbench completion bash)"` to ~/.bashrc.',
    )
    p.add_argument("shell", nargs="?", default="bash", choices=("bash", "zsh", "fish", "tcsh"),
                   help="the shell to print the code for (default bash)")  # fmt: skip
    p.set_defaults(func=_completion)


#: What reads as a negative number, not an option: argparse's own matcher (Python 3.11) takes -1 and -0.5 but not
#: -1e-3, so ``legbench model fk 0.1 -1e-3 0.2`` was refused as an unknown option -1e-3.
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class _Parser(argparse.ArgumentParser):
    """argparse's parser with its errors on one line (argparse prints the usage block first), exit status 2, and
    a negative number in exponent notation read as a value (:data:`_NEGATIVE_NUMBER`; argparse has no public
    setting for it). Subcommand parsers are of the same class (``add_subparsers`` makes them so)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USER_ERROR, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The parser; with ``argv`` naming a subcommand, only that subcommand's module is imported."""
    parser = _Parser(
        prog="legbench", description="Compare physics engines on the 3-DOF leg: run, compare, check, study."
    )
    parser.add_argument("--version", action="version", version=f"legbench {__version__}")
    parser.add_argument(
        "--model",
        metavar="PATH",
        default=None,
        help=f"another leg parameter file (the format of models/leg.yaml; also ${resources.MODEL_ENV})",
    )
    sub = parser.add_subparsers(dest="cmd", required=True)
    first = _first_command(argv or ())
    if first in COMMANDS:
        wanted = [first]
    elif argv is None:  # the whole tree (introspection, tests)
        wanted = list(COMMANDS)
    else:  # no subcommand named (`legbench --help`, a typo): list them from SUMMARY, import none
        for name in COMMANDS:
            sub.add_parser(name, help=SUMMARY[name], add_help=False)
        wanted = []
    for name in wanted:
        module, func = COMMANDS[name].split(":")
        getattr(importlib.import_module(module), func)(sub)
        page = sub.choices.get(name)
        if page is not None and not page.description:  # `legbench NAME --help` says what it does, as the list does
            page.description = SUMMARY[name][:1].upper() + SUMMARY[name][1:] + "."
    return parser


def _select_model(path: str) -> None:
    """Make ``path`` the active leg model after checking it reads (a bad file is one line, exit 2)."""
    from legbench import model

    if not path:  # Path("") is the working directory
        raise ModelError("--model '': an empty path (give a leg parameter file)")
    file = Path(path)
    kind = _not_a_model_file(file)
    if kind:
        raise ModelError(f"--model {path}: {kind}")
    model.load_params(file)  # raises ModelError naming the file and the entry
    resources.select_model(file)


def _not_a_model_file(file: Path) -> str:
    """Why ``file`` cannot be a leg parameter file ('' if it is a regular file), without opening it: a device
    such as /dev/zero has no end and a FIFO blocks until a writer comes."""
    try:
        if file.is_file():
            return ""
        if file.exists():
            return "is a directory" if file.is_dir() else "is not a regular file"
        return "no such parameter file"
    except OSError as exc:  # a name too long
        return str(exc.strerror or exc)


def _check_model_env() -> None:
    """``LEGBENCH_MODEL`` naming no regular file is refused before any subcommand's module is imported, with the
    variable's name: the library refuses it too where it reads the file (``legbench.model.param_bytes`` for the
    URDF's name, the YAML reader), but naming the file only; a device or a FIFO there was once read without end
    (/dev/zero until the process was killed) or blocked for ever."""
    path = resources.env_path(resources.MODEL_ENV)  # a ~user that cannot be expanded: one line naming the variable
    if path is not None:
        kind = _not_a_model_file(path)
        if kind:
            raise ModelError(f"{resources.MODEL_ENV}={os.environ[resources.MODEL_ENV]}: {kind}")


_KEPT = "what finished is kept (lines above), rerun the same command to finish"
#: What an interrupt leaves, by subcommand: the runs keep what finished; the studies write only at the end.
_INTERRUPTED: dict[str, str] = {
    "run": _KEPT,
    "sweep": "what finished is kept (lines above); a sweep is not resumed: rerun it with --force to replace it",
    "reproduce": _KEPT,
    **dict.fromkeys(("verify", "calibrate-contact", "bench"), "nothing was written (it writes when all is done)"),
}


#: Subcommands that load engines (each loads the active model's URDF, from the cache for another model).
_LOADS_ENGINES = ("run", "doctor", "sweep", "verify", "calibrate-contact", "bench", "reproduce")
#: Subcommands whose ``--out`` is a directory (``model urdf --out`` is a file).
_OUT_DIRS = ("run", "sweep", "bench", "verify", "calibrate-contact", "reproduce")


#: Address schemes of a Dask scheduler (distributed's communication back-ends).
_SCHEMES = ("tcp", "tls", "inproc", "ws", "wss", "ucx")


def _check_outputs(args: argparse.Namespace) -> None:
    """Options every writing subcommand shares, checked before any work: ``--jobs`` >= 1, ``--out`` a usable
    directory (or file for ``model urdf``: :func:`legbench.results.check_out_file`, a regular file or none, not in a
    run directory), ``--summary``/``--junit`` files in an existing folder, regular files or none (never a link or a
    device, even with ``--force``), that replace an existing file only with ``--force`` (the defaults in the results
    directory are rewritten freely)."""
    from legbench import results  # the subcommand's module has imported it already

    jobs = getattr(args, "jobs", None)
    if jobs is not None and jobs < 1:
        raise LegbenchError(f"--jobs {jobs}: must be at least 1")
    out = getattr(args, "out", None)
    if out == "":
        raise LegbenchError("--out '': an empty path (give a directory, or leave --out out for the default)")
    if out is not None:
        if args.cmd in _OUT_DIRS:
            results.check_out_path(out, run_dir_ok=args.cmd == "run")  # run resumes or replaces its own
        else:
            try:
                results.check_out_file(out)
            except (OSError, RuntimeError) as exc:  # a name too long, a loop of links: a place that cannot be
                raise LegbenchError(f"--out {out}: {getattr(exc, 'strerror', None) or exc}") from None
    scheduler = getattr(args, "scheduler", None)
    if scheduler is not None:
        scheme, sep, rest = str(scheduler).rpartition("://")
        host, colon, port = rest.rpartition(":")
        needs_port = scheme != "inproc"  # distributed's in-process transport has no port
        if (sep and scheme not in _SCHEMES) or not rest or (needs_port and not (host and colon and port.isdigit())):
            raise LegbenchError(f"--scheduler {scheduler}: expected an address such as tcp://host:8786 "
                                f"(schemes: {', '.join(_SCHEMES)})")  # fmt: skip
    for opt in ("summary", "junit"):
        if getattr(args, opt, None) is not None:
            try:
                # inside a run directory: legbench.check's rule (its own summaries may go there)
                path = results.check_out_file(getattr(args, opt), f"--{opt}", in_run_ok=True)
                exists = path.exists()
            except (OSError, RuntimeError) as exc:
                raise LegbenchError(f"--{opt} {getattr(args, opt)}: {getattr(exc, 'strerror', None) or exc}") from None
            if exists and not getattr(args, "force", False):
                raise LegbenchError(f"--{opt} {path}: exists; choose another file, or pass --force to replace it")


def _stdout_closed() -> bool:
    """Whether stdout is a pipe whose reader is gone (``poll`` reports an error on its write end); if so stdout
    goes to /dev/null from here, so the interpreter's last flush at exit prints no traceback of its own."""
    try:
        fd = sys.stdout.fileno()
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        closed = any(events & select.POLLERR for _, events in poller.poll(0))
    except (OSError, ValueError, AttributeError):  # no file descriptor (a test's captured stdout)
        return False
    if closed:
        os.dup2(os.open(os.devnull, os.O_WRONLY), fd)
    return closed


def _sigterm(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _redeliver(previous: Callable[[sys.UnraisableHookArgs], object]) -> Callable[[sys.UnraisableHookArgs], None]:
    """The unraisable hook of a command: an interrupt that Python could not raise where it arrived (Ctrl-C during an
    import lands, now and then, in importlib's module-lock weakref callback, which printed "Exception ignored" and
    carried on: the run went to its end, exit status 0) is raised again in the main thread; anything else goes to
    ``previous``.

    Raised again through the SIGTERM handler :func:`main` installs (``_thread.interrupt_main``), from a thread that
    waits until the main thread has left this hook: raised within it, the interrupt would be ignored for good. Where
    it lands in another such callback, that callback reports it here again."""

    def hook(unraisable: sys.UnraisableHookArgs) -> None:
        if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            threading.Thread(target=_interrupt_main_after, args=(hook.__code__,), daemon=True).start()
            return
        previous(unraisable)

    return hook


def _interrupt_main_after(code: CodeType) -> None:
    """Interrupt the main thread (its SIGTERM handler) once no frame of its stack runs ``code``."""
    import _thread
    import time

    main = threading.main_thread().ident
    while main is not None:
        frame = sys._current_frames().get(main)
        while frame is not None and frame.f_code is not code:
            frame = frame.f_back
        if frame is None:
            break
        time.sleep(0.001)  # the main thread is still in the hook: it returns within microseconds
    _thread.interrupt_main(signal.SIGTERM)


def main(argv: Sequence[str] | None = None) -> int:
    previous = signal.signal(signal.SIGTERM, _sigterm)  # before anything slow
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _redeliver(previous_hook)
    try:
        argv = sys.argv[1:] if argv is None else list(argv)
        if "_ARGCOMPLETE" in os.environ:  # tab completion: import only the subcommand being completed
            import argcomplete

            argcomplete.autocomplete(build_parser(os.environ.get("COMP_LINE", "").split()[1:]))
        _check_model_env()
        args = build_parser(argv).parse_args(argv)
        if args.model is not None:
            _select_model(args.model)
        _check_outputs(args)
        if args.cmd in _LOADS_ENGINES:  # the URDF now: a bad cache directory is one line, not every engine's failure
            resources.urdf_file()
        return int(args.func(args))
    except LegbenchError as exc:
        print(f"legbench: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USER_ERROR
    except BrokenPipeError as exc:  # stdout's reader went away (| head): quiet, with the shell's SIGPIPE status
        if _stdout_closed():
            return EXIT_OUTPUT_CLOSED
        print(_one_line(f"legbench: I/O error: {exc.strerror or exc}; nothing was replaced"), file=sys.stderr)
        return EXIT_IO_ERROR
    except OSError as exc:  # full disk, read-only or vanished output: one line, the previous result is intact
        where = f" {exc.filename}:" if exc.filename else ""
        print(_one_line(f"legbench: I/O error:{where} {exc.strerror or exc}; nothing was replaced"), file=sys.stderr)
        return EXIT_IO_ERROR
    except RecursionError:
        print("legbench: error: input nested too deep", file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print(f"legbench: interrupted; {_INTERRUPTED.get(_first_command(argv or ()) or '', 'stopped')}",
              file=sys.stderr)  # fmt: skip
        return EXIT_INTERRUPTED
    finally:
        sys.unraisablehook = previous_hook
        signal.signal(signal.SIGTERM, previous)


def _one_line(message: object) -> str:
    """A message on one line whatever the user's input in it holds (:func:`legbench.yamlfile.one_line`)."""
    from legbench.yamlfile import one_line  # only when there is an error to print

    return one_line(str(message))


def entry() -> int:
    """The ``legbench`` command itself (the console script, ``python -m legbench``): :func:`main`, then
    :func:`gc.freeze`, so the interpreter's final garbage collections at exit skip the objects the
    command leaves behind. After a run or a sweep that held engines, logs and figures those scans took
    0.45-0.5 s of the exit (0.65 -> 0.15 s after the time-step sweep with ``--jobs 1``); by then every
    file is written and closed, and the operating system takes the memory back. Not part of
    :func:`main`, which tests and scripts call inside their own long-lived processes."""
    status = main()
    gc.freeze()
    return status


if __name__ == "__main__":
    sys.exit(entry())

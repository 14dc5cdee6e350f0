"""Hydra's command line, written out the one way fuzzynav's commands and Hydra both read it.

Hydra's own parser (argparse) takes its options abbreviated (``--multi`` for ``--multirun``, ``-cjob`` for ``--cfg
job``) and refuses config overrides on both sides of an option (``planner=wait --cfg job seed=1``: eight lines of
usage). The commands' own checks looked for the options as written: ``runners.run --multi`` ran Hydra's multirun
without a summary, ``runners.sweep -cjob`` was given ``--multirun`` next to it (a traceback). Every command line is
therefore read once by Hydra's parser, overrides intermixed with options, and written out again: Hydra's options
in full, then the arguments it does not know (``--debug``), then the overrides in their order. What that parser
cannot read (``--cfg`` without its value) is one line, as are two options of which Hydra takes only one.
"""

from __future__ import annotations

import contextlib
import io

EXCLUSIVE = ("run", "multirun", "cfg", "info", "shell_completion")
"""Hydra's options of which a command line may give one (its "Only one of --run, --multirun, ...")."""

_FLAGS = (("help", "--help"), ("hydra_help", "--hydra-help"), ("resolve", "--resolve"), ("run", "--run"),
          ("multirun", "--multirun"), ("shell_completion", "--shell-completion"))
_VALUED = (("cfg", "--cfg"), ("package", "--package"), ("config_path", "--config-path"),
           ("config_name", "--config-name"), ("config_dir", "--config-dir"),
           ("experimental_rerun", "--experimental-rerun"), ("info", "--info"))


def canonical_arguments(args: list[str]) -> tuple[list[str], str | None]:
    """(``args`` written out as the module says, or as given where Hydra answers them itself: ``--help``,
    ``--version``; one line about what Hydra's parser cannot read, or None)."""
    from hydra._internal.utils import get_args_parser  # its parser: the options are Hydra's, not a copy of them

    parser = get_args_parser()
    errors = io.StringIO()
    try:
        with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
            # the options Hydra does not know (fuzzynav's --debug) set aside: argparse took the overrides after one
            # for its values, and gave them back out of their order
            unknown = [arg for arg in args if arg.startswith("-") and _unknown_option(parser, arg)]
            rest = list(args)
            for arg in unknown:
                rest.remove(arg)
            known = parser.parse_intermixed_args(rest)
    except SystemExit as exit_:
        if exit_.code in (0, None):  # --version: Hydra prints it
            return args, None
        lines = errors.getvalue().strip().splitlines()
        message = lines[-1].partition(": error: ")[2] if lines else ""
        return args, f"{message[:200] or 'the options cannot be read'} (see --help)"
    if known.help or known.hydra_help:  # Hydra's help, as the user asked for it
        return args, None
    given = [name for name in EXCLUSIVE if getattr(known, name)]
    if len(given) > 1:
        names = " and ".join("--" + name.replace("_", "-") for name in given)
        return args, f"{names}: Hydra takes one of --run, --multirun, --cfg, --info and --shell-completion"
    out = [flag for name, flag in _FLAGS if getattr(known, name)]
    for name, option in _VALUED:
        value = getattr(known, name)
        if value is not None:
            out += [option, str(value)]
    return [*out, *unknown, *known.overrides], None


def _unknown_option(parser: object, arg: str) -> bool:
    """Whether ``arg`` is none of the parser's options (abbreviations included)."""
    try:
        return bool(parser.parse_known_args([arg.partition("=")[0]])[1])  # type: ignore[attr-defined]
    except SystemExit:  # one of its options, without its value
        return False

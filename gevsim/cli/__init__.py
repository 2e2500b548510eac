"""Command line: ``gevsim info``, ``scenes``, ``presets``, ``render``, ``emulate``, ``reconstruct``, ``export``,
``study``, ``dataset``, ``validate``, ``train``, ``score``.

The CLI parses arguments, sets up logging and progress bars and calls the
library; one module per group of commands. Bad input (:class:`~gevsim.errors.ConfigError`)
and a missing optional extra (:class:`~gevsim.errors.MissingExtraError`) print one line
naming the file and key and exit with code 2, as does a checked value out of range
(:class:`~gevsim._validate.FieldError`, raised where a flag's value first meets its physics);
anything else is a bug and shows its traceback.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import sys
from concurrent.futures import BrokenExecutor
from pathlib import Path

from gevsim._validate import FieldError
from gevsim.cli._common import _progress
from gevsim.cli.emulate import cmd_emulate
from gevsim.cli.files import cmd_export, cmd_reconstruct, cmd_score, cmd_view
from gevsim.cli.info import cmd_info, cmd_presets, cmd_scenes, cmd_validate
from gevsim.cli.parser import build_parser
from gevsim.cli.render import cmd_render
from gevsim.cli.runs import cmd_dataset, cmd_study
from gevsim.cli.train import cmd_train
from gevsim.errors import GevsimError, clipped, one_line

__all__ = ["build_parser", "main", "_progress", "cmd_dataset", "cmd_emulate", "cmd_export", "cmd_info",
           "cmd_presets", "cmd_reconstruct", "cmd_render", "cmd_scenes", "cmd_score", "cmd_study", "cmd_train",
           "cmd_validate", "cmd_view"]


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    own = logging.getLogger("gevsim")
    level = own.level  # restored on return: a caller in the same process (a test, a notebook) keeps its own
    if args.verbose:  # gevsim's own debug messages, not those of every library it imports
        own.setLevel(logging.DEBUG)
    try:
        return globals()[f"cmd_{args.command}"](args)
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0
    except GevsimError as exc:  # bad input, or an optional extra (plot, dask, video) is missing
        if args.verbose:
            raise
        print(f"gevsim: error: {exc}", file=sys.stderr)
        return 2
    except FieldError as exc:  # a checked value out of range (a flag's value the parser cannot bound): bad input
        if args.verbose:
            raise
        print(f"gevsim: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("gevsim: interrupted", file=sys.stderr)
        return 130
    except MemoryError as exc:  # past the estimates checked up front (they leave out what depends on the data)
        if args.verbose:
            raise
        print(f"gevsim: error: out of memory ({one_line(exc) or 'MemoryError'}): emulate a smaller size, a shorter "
              "duration or fewer chunk_steps or frames", file=sys.stderr)
        return 2
    except BrokenExecutor as exc:  # a worker was killed (out of memory, a signal): not bad input, but no traceback
        if args.verbose:
            raise
        print(f"gevsim: error: a worker process died ({exc}); finished runs are kept, the same command resumes",
              file=sys.stderr)
        return 1
    except (OSError, RuntimeError) as exc:  # a full disk, a quota, a read-only file system: one line
        error = exc
        if isinstance(exc, RuntimeError):  # h5py's and OpenEXR's, from a worker too: the errno is in the text
            from gevsim.io._h5discard import disk_error

            error = disk_error(exc, None) or exc
        if not isinstance(error, OSError) or error.errno not in DISK_ERRORS + PATH_ERRORS or args.verbose:
            raise
        where = _failed_path(error.filename, str(exc)) or (f"{args.out}: " if getattr(args, "out", None) else "")
        print(f"gevsim: error: {where}{os.strerror(error.errno).lower()}", file=sys.stderr)
        return 2
    finally:
        own.setLevel(level)


#: errno values that mean "this disk cannot take the output" rather than a bug.
DISK_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG)
#: errno values that mean "no such path can exist here" (a name past the file system's limit, a loop of links).
PATH_ERRORS = (errno.ENAMETOOLONG, errno.ELOOP)


def _failed_path(name: str | bytes | None, message: str) -> str:
    """``"<path>: "`` of the file a write failed on (the target rather than its temporary stage), or ``""``."""
    if name is None:  # h5py puts the name into the message only: "filename = '...'"
        found = re.search(r"filename = '([^']*)'", message)
        name = found.group(1) if found else None
    if name is None:
        return ""
    from gevsim.io.atomic import _STAGE

    parts = Path(os.fsdecode(name)).parts
    for i, part in enumerate(parts):  # a stage ".<target>.gevsim-XXXXXXXX<suffix>" stands for its target
        staged = _STAGE.match(part)
        if staged:
            return f"{clipped(str(Path(*parts[:i], staged['name'])))}: "
    return f"{clipped(str(Path(*parts)))}: "

"""Output files and folders, checked before any work: one policy for every command.

The policy: missing parent folders are created; a path that cannot be
written (an existing folder where a file is asked for, a file where a
folder is needed, no permission) is refused before the command starts,
with one line and exit status 2.
"""

import os
import pathlib

from fusion_planner.core.errors import InvalidInput


class OutputPathError(InvalidInput):
    """An output path that cannot be written (exit 2, one line)."""

    outcome = 'invalid_output_path'


def prepare_file(path, option):
    """Make sure ``path`` can be written as a file; create its missing folders.

    Parameters
    ----------
    path : str or os.PathLike
        The file a command will write.
    option : str
        The option that named it (``'--plot'``), for the message.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    OutputPathError
        If ``path`` is a folder, a part of its parent path is a file, or its
        folder cannot be created or written to.
    """
    path = pathlib.Path(path)
    try:
        if path.is_dir():
            raise OutputPathError(f'cannot write {option} {path}: it is a folder')
        _make_folder(path.parent, option, path)
        if path.exists() and not os.access(path, os.W_OK):
            raise OutputPathError(f'cannot write {option} {path}: permission denied')
    except OSError as err:  # a name the file system refuses (too long, ...)
        raise OutputPathError(f'cannot write {option} {path}: {err.strerror or err}') from None
    return path


def prepare_folder(path, option):
    """Make sure ``path`` is a writable folder, creating it (and its parents) if missing.

    Parameters and result as for :func:`prepare_file`, ``path`` being the
    folder a command writes its files into.

    Raises
    ------
    OutputPathError
        If ``path`` or a part of it is a file, or it cannot be created or
        written to.
    """
    path = pathlib.Path(path)
    try:
        _make_folder(path, option, path)
    except OSError as err:
        raise OutputPathError(f'cannot write {option} {path}: {err.strerror or err}') from None
    return path


def _make_folder(folder, option, target):
    """Create ``folder`` with its parents and check it is writable; ``target`` names the output.

    Raises :class:`OutputPathError`, or ``OSError`` from the file system.
    """
    for part in (folder, *folder.parents):
        if part.exists() and not part.is_dir():
            raise OutputPathError(f'cannot write {option} {target}: {part} is not a folder')
    folder.mkdir(parents=True, exist_ok=True)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(f'cannot write {option} {target}: {folder} is not writable')

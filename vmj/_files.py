"""Writing files: output paths checked before any work, and written atomically.

Every file vmj writes (figures, sweep CSV and NetCDF exports) goes through [`replacing`][]: the
content is written to a temporary file in the same directory, which then replaces the target in
one `os.replace`, so that a full disk or a killed process never leaves a truncated file behind.
A symbolic link is followed (the file it points to is replaced, the link stays); a device or a
pipe (`/dev/null`, `/dev/stdout`) is written to directly. Nothing creates directories or renames
a file silently.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile

__all__ = ["check_writable", "replacing"]


def check_writable(path, name: str = "path") -> str:
    """Return `path` (a string) after checking that a file can be written there: it is not a
    directory, and its directory exists and is writable. `ValueError` naming `name` otherwise."""
    path = os.fspath(path)
    if not path or not path.strip():
        raise ValueError(f"{name} must be a file path (got an empty string)")
    if os.path.isdir(path):
        raise ValueError(f"{name} {path!r} is a directory; give a file path")
    if _special(path):
        if not os.access(path, os.W_OK):
            raise ValueError(f"{name} {path!r} is not writable")
        return path
    folder = os.path.dirname(os.path.realpath(path))
    if not os.path.isdir(folder):
        raise ValueError(
            f"{name} {path!r}: the directory {folder} does not exist (vmj creates no directories)"
        )
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{name} {path!r}: the directory {folder} is not writable")
    return path


@contextlib.contextmanager
def replacing(path, name: str = "path", seekable: bool = False):
    """Context manager yielding a temporary path next to `path`; on success the temporary file
    replaces `path` atomically (with the permissions a new file would get, or those of the file
    it replaces); on any error it is removed and `path` is left as it was. A device or a pipe
    is written to in place, or, for a writer that needs a `seekable` file (NetCDF's HDF5,
    which failed on /dev/null), through a temporary file copied into it."""
    path = check_writable(path, name)
    if _special(path):
        if not seekable:
            yield path
            return
        fd, tmp = tempfile.mkstemp(suffix=os.path.splitext(path)[1] or None, prefix=".vmj-")
        os.close(fd)
        try:
            yield tmp
            with open(tmp, "rb") as src, open(path, "wb") as dst:
                shutil.copyfileobj(src, dst)
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        return
    path = os.path.realpath(path)  # a symbolic link: the file it points to
    folder = os.path.dirname(path)
    suffix = os.path.splitext(path)[1] or None
    fd, tmp = tempfile.mkstemp(suffix=suffix, prefix=".vmj-", dir=folder)
    os.close(fd)
    try:
        yield tmp
        if os.path.exists(path):
            mode = stat.S_IMODE(os.stat(path).st_mode)
        else:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _special(path) -> bool:
    """Whether `path` is (or links to) something other than a regular file or a directory: a
    device or a pipe, written to in place."""
    return os.path.exists(path) and not os.path.isfile(path) and not os.path.isdir(path)

"""
Durable writes of a sweep's text files (manifest, summary, verdict).

Apart from ``engine`` so that ``report`` and ``verdict`` can use it without importing the
engine (and Dask with it) or making an import cycle.
"""

import os


def write_text_atomic(path, text):
    """
    Write a text file whole or not at all, as ``engine.write_atomic`` writes a part.

    A summary torn by a power cut would be read back as the sweep's result (the parts
    were already written whole; the JSON files beside them were written without fsync).
    """
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    fsync_dir(path.parent)


def fsync_dir(directory):
    """Make a rename in ``directory`` durable (POSIX: fsync the directory itself)."""
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)

"""HDF5 datasets as the event readers need them: the right kind and shape, read in checked blocks.

h5py hands back whatever a file holds: a group where a dataset is meant, strings, compound records, a
2-element array where one number is meant, and raises its own words (or a numpy error) when a damaged
compressed chunk cannot be decoded. These helpers refuse each case in one line that names the file and the
dataset, and say what the dataset should hold.
"""

from __future__ import annotations

import numpy as np

from cvstereo.errors import CorruptFileError
from cvstereo.model.columns import INT64_MAX, first_bad


def h5py_module():
    """h5py, with the compression filters DSEC files use registered (hdf5plugin); ImportError names the extra."""
    try:
        import h5py
        import hdf5plugin  # noqa: F401 -- registers the compression filters DSEC files use (Blosc, Zstd)
    except ImportError as exc:
        raise ImportError("reading HDF5 event files needs h5py and hdf5plugin: pip install 'cvstereo[hdf5]'") from exc
    return h5py


def numeric_dataset(f, path, key: str, *, ndim: int, holds: str, integers: bool = False):
    """The dataset ``/key`` of an open file, refused unless it is a dataset of numbers with ``ndim`` dimensions.

    Parameters
    ----------
    f : h5py.File
    path : path-like
        Named in messages.
    key : str
        Dataset path inside the file, without the leading ``/``.
    ndim : int
        Dimensions the dataset must have.
    holds : str
        What it should hold, for the message ("pixel columns (uint16)").
    integers : bool, keyword-only
        Refuse floats too (index tables).

    Raises
    ------
    CorruptFileError
    """
    node = f.get(key)
    if not isinstance(node, h5py_module().Dataset):
        what = "missing" if node is None else f"a {type(node).__name__.lower()}, not a dataset"
        raise CorruptFileError(f"{path}: /{key} is {what}; it should hold {holds}.")
    kinds = "iub" if integers else "iufb"
    if node.dtype.kind not in kinds:
        what = {"S": "strings", "U": "strings", "O": "strings or objects", "V": "records"}.get(node.dtype.kind,
                                                                                             "values")
        raise CorruptFileError(f"{path}: /{key} holds {what} (dtype {node.dtype}); it should hold {holds}.")
    if node.ndim != ndim:
        raise CorruptFileError(f"{path}: /{key} has shape {node.shape}; it should be {ndim}-D and hold {holds}.")
    return node


def integer_scalar(f, path, key: str, *, holds: str) -> int:
    """The one integer a dataset such as DSEC's ``/t_offset`` holds (shape () or (1,)), refused otherwise."""
    node = f.get(key)
    dataset = isinstance(node, h5py_module().Dataset)
    if not dataset or node.dtype.kind not in "iu" or node.size != 1:
        what = (f"a {type(node).__name__.lower()}" if not dataset else
                f"dtype {node.dtype} and shape {node.shape}")
        raise CorruptFileError(f"{path}: /{key} has {what}; it should be one integer: {holds}.")
    value = int(np.asarray(node[()]).reshape(-1)[0])
    if value > INT64_MAX:
        raise CorruptFileError(f"{path}: /{key} is {value}, beyond int64; it should be {holds}.")
    return value


def read_rows(dataset, path, key: str, lo: int, hi: int) -> np.ndarray:
    """``dataset[lo:hi]``, or a one-line error naming the file, the dataset and the rows when it cannot be decoded
    (a damaged compressed chunk makes h5py raise its own words without the file's name)."""
    try:
        return dataset[lo:hi]
    except (OSError, ValueError, RuntimeError) as exc:
        raise CorruptFileError(f"{path}: /{key} rows {lo}..{hi - 1} cannot be read ({exc}); the file is "
                               "damaged.") from None


def check_index_block(block: np.ndarray, previous: int | None, n: int, *, path, key: str,
                      index_offset: int) -> int | None:
    """Check one block of an index table (entries are event indices): each within ``0..n``, none smaller than the
    one before (``previous``: the last entry of the preceding block). Returns the block's last entry.

    Raises
    ------
    CorruptFileError
        Naming the table, the first bad entry's index and value, and what to do.
    """
    if block.size == 0:
        return previous
    outside = (block < 0) | (block > n) if block.dtype.kind == "i" else block > n
    i = first_bad(outside)
    if i is not None:
        raise CorruptFileError(f"{path}: /{key} at index {index_offset + i} is {block[i].item()}, outside 0..{n} "
                               f"(the file holds {n} events){_index_fix(key)}")
    back = block[1:] < block[:-1]
    if previous is not None and block[0] < previous:
        i, before = 0, previous
    elif back.any():
        i = int(np.argmax(back)) + 1
        before = block[i - 1].item()
    else:
        return block[-1].item()
    raise CorruptFileError(f"{path}: /{key} at index {index_offset + i} is {block[i].item()}, less than the entry "
                           f"before it ({before}); the index never decreases{_index_fix(key)}")


def _index_fix(key: str) -> str:
    return (f"; the index is damaged: rebuild it, or delete it (h5py: del f['{key}']) and the events are read in "
            "blocks of rows.")

"""Reading and writing files safely: the one gate every file the tools read or write goes through.

Reads:

- :func:`read_bytes` opens without blocking and checks the open file itself: it must be a regular file (not a folder,
  a FIFO, a device such as ``/dev/zero``, or a socket) no larger than a limit, so nothing hangs and nothing is read
  without bound. Path problems (missing, a symbolic-link loop, a file used as a folder, a name too long, no
  permission) become one-line :class:`InputFileError` messages that name the file.
- :func:`read_text`, :func:`read_json` (UTF-8, no NaN or Infinity, nesting limited), :func:`parse_json` (the same
  for text already read, such as one line of a JSON-lines file) and :func:`read_npy` (the header checked against
  the data before anything is allocated; numbers only, never pickles), :func:`read_npz` (each member so checked,
  and the whole bounded unpacked as well as on disk), :func:`read_png` (its pixel count read from the header before
  anything is decoded), and :func:`read_weights` (a flat vector of a known length, such as an NCA's weights, from
  ``.npy`` or ``.json``).

Writes: :func:`atomic_write` writes a temporary file beside the target and renames it into place, so readers see the
old file or the complete new one; path problems are :class:`InputFileError` as for reads. :func:`check_output` runs
the same checks before any work, so a command fails fast on a bad output path, and :func:`check_not_an_input` that
writing an output cannot replace one of the command's inputs.

Limits are generous (far above anything structgen writes) and exist to turn absurd inputs into clear errors.
"""

from __future__ import annotations

import errno
import io
import json
import os
import stat
import uuid
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "GiB",
    "MiB",
    "InputFileError",
    "atomic_write",
    "write_table",
    "check_output",
    "check_not_an_input",
    "parse_json",
    "path_error",
    "read_bytes",
    "read_json",
    "read_npy",
    "read_npz",
    "read_png",
    "parse_npy",
    "read_weights",
    "read_text",
]

MiB = 1 << 20
GiB = 1 << 30
#: JSON nested deeper than this is refused (our files nest a few levels).
MAX_JSON_DEPTH = 200

_PATH_PROBLEMS = {
    errno.ENOENT: "no such file",
    errno.ELOOP: "too many levels of symbolic links (a link loop?)",
    errno.ENOTDIR: "a part of the path is a file, not a folder",
    errno.ENAMETOOLONG: "file name too long",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.EISDIR: "is a folder",
    errno.EROFS: "read-only file system",
}


class InputFileError(ValueError):
    """A file cannot be read or written as asked: the message names the file and what is wrong with it."""


def path_error(path: str | os.PathLike, err: OSError, *, writing: bool = False) -> InputFileError | OSError:
    """The user's mistake in ``err`` as an InputFileError naming ``path``; any other OSError unchanged."""
    problem = _PATH_PROBLEMS.get(err.errno or 0)
    if writing and err.errno == errno.ENOENT:
        problem = "no such folder"
    if writing and err.errno == errno.EEXIST:  # making a folder where a file is
        problem = "a part of the path is a file, not a folder"
    if problem is None:
        return err
    return InputFileError(f"{path}: {problem}")


def _size(n: float) -> str:
    return f"{n / MiB:,.0f} MiB" if n >= MiB else f"{n:,.0f} bytes"


def read_bytes(path: str | os.PathLike, limit: int) -> bytes:
    """The whole content of the regular file at ``path``, at most ``limit`` bytes."""
    try:
        # Non-blocking, so that a FIFO with no writer cannot hang us before fstat tells what it is.
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as err:
        raise path_error(path, err) from None
    try:
        info = os.fstat(descriptor)
        if stat.S_ISDIR(info.st_mode):
            raise InputFileError(f"{path}: is a folder, expected a file")
        if not stat.S_ISREG(info.st_mode):
            raise InputFileError(f"{path}: not a regular file (a FIFO, a device or a socket), refusing to read it")
        if info.st_size > limit:
            raise InputFileError(f"{path}: is {_size(info.st_size)}, more than the {_size(limit)} this file may hold")
        os.set_blocking(descriptor, True)
        chunks, total = [], 0
        while True:  # read to the end: the size may have changed since fstat
            chunk = os.read(descriptor, min(limit + 1 - total, 1 << 24) or 1)
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > limit:
                raise InputFileError(f"{path}: grew past the {_size(limit)} this file may hold while being read")
        return b"".join(chunks)
    except OSError as err:
        raise path_error(path, err) from None
    finally:
        os.close(descriptor)


def read_text(path: str | os.PathLike, limit: int, *, what: str = "text") -> str:
    """The file at ``path`` as UTF-8 text."""
    data = read_bytes(path, limit)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise InputFileError(f"{path}: not a text file (expected {what})") from None


def _no_constants(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


def parse_json(text: str, source: str) -> Any:
    """``text`` as JSON, refusing NaN and Infinity and nesting deeper than :data:`MAX_JSON_DEPTH`; ``source`` names
    where the text came from in error messages."""
    try:
        data = json.loads(text, parse_constant=_no_constants)
    except json.JSONDecodeError as err:
        raise InputFileError(f"{source}: not valid JSON (line {err.lineno}, column {err.colno}: {err.msg})") from None
    except ValueError as err:
        raise InputFileError(f"{source}: not valid JSON ({err})") from None
    except RecursionError:
        raise InputFileError(f"{source}: JSON nested too deeply") from None
    depth, surrogate = _shape(data)
    if depth > MAX_JSON_DEPTH:
        raise InputFileError(f"{source}: JSON nested more than {MAX_JSON_DEPTH} levels deep")
    if surrogate is not None:
        # JSON's \ud800 escapes can spell half a character, which no file or terminal can hold as text.
        raise InputFileError(f"{source}: holds {ascii(surrogate)}, a lone UTF-16 surrogate, which is not text")
    return data


def _shape(value: Any) -> tuple[int, str | None]:
    """How deeply ``value`` nests lists and objects, and the first string (key or value) holding a lone surrogate,
    found without recursion."""
    deepest, stack, surrogate = 0, [(value, 1)], None
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            if surrogate is None:
                surrogate = next((key for key in item if _has_surrogate(key)), None)
            item = list(item.values())
        if isinstance(item, list):
            deepest = max(deepest, depth)
            for child in item:
                if isinstance(child, (list, dict)):
                    stack.append((child, depth + 1))
                elif surrogate is None and isinstance(child, str) and _has_surrogate(child):
                    surrogate = child
        elif isinstance(item, str) and surrogate is None and _has_surrogate(item):
            surrogate = item
    return deepest, surrogate


def _has_surrogate(text: str) -> bool:
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return True
    return False


def read_json(path: str | os.PathLike, limit: int, *, what: str = "JSON") -> Any:
    """The JSON document in the file at ``path`` (see :func:`parse_json`)."""
    return parse_json(read_text(path, limit, what=what), str(path))


def read_npy(path: str | os.PathLike, limit: int) -> np.ndarray:
    """The numeric array in the ``.npy`` file at ``path`` (:func:`parse_npy`)."""
    return parse_npy(read_bytes(path, limit), str(path))


def parse_npy(data: bytes, source: str, *, text: bool = False) -> np.ndarray:
    """The array in ``data``, the bytes of a ``.npy`` file (``source`` names it in errors).

    The header is read first and checked against the bytes that follow, so a header that claims more data than the
    file holds is an error, not an allocation; object arrays (pickles) and non-numeric types are refused (``text``
    admits arrays of text, which are not pickles either).
    """
    stream = io.BytesIO(data)
    try:
        version = np.lib.format.read_magic(stream)
        reader = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, fortran, dtype = reader(stream)
    except Exception as err:  # numpy says ValueError for most damage, other errors for some
        raise InputFileError(f"{source}: not a valid .npy file ({err})") from None
    kinds = "biufU" if text else "biuf"
    if dtype.hasobject or dtype.kind not in kinds or dtype.fields is not None or dtype.subdtype is not None:
        raise InputFileError(f"{source}: holds {dtype} values; expected {'numbers or text' if text else 'numbers'}")
    count = int(np.prod(shape, dtype=object))
    body = len(data) - stream.tell()
    if count * dtype.itemsize != body:
        raise InputFileError(
            f"{source}: its header says shape {tuple(shape)} of {dtype} ({_size(count * dtype.itemsize)}), "
            f"but {_size(body)} follow it (the file is cut short or damaged)"
        )
    array = np.frombuffer(data, dtype=dtype, count=count, offset=stream.tell())
    return array.reshape(shape, order="F" if fortran else "C").copy()


def read_npz(path: str | os.PathLike, limit: int, unpacked: int, *, text: bool = False) -> dict[str, np.ndarray]:
    """The arrays of the ``.npz`` archive at ``path`` by name, each checked as :func:`parse_npy` checks one.

    The archive is at most ``limit`` bytes on disk and ``unpacked`` bytes unpacked: each member is read at most to
    what is left of that, whatever its header claims, so a small file that inflates to gigabytes is an error, not
    an allocation."""
    import zipfile

    data = read_bytes(path, limit)
    try:
        archive = zipfile.ZipFile(io.BytesIO(data))
        members = archive.infolist()
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as err:
        raise InputFileError(f"{path}: not a .npz archive ({err})") from None
    arrays: dict[str, np.ndarray] = {}
    left = unpacked
    for member in members:
        name = member.filename[:-4] if member.filename.endswith(".npy") else member.filename
        if member.file_size > left:
            raise InputFileError(f"{path}: unpacks to more than the {_size(unpacked)} this file may hold ({name})")
        try:
            with archive.open(member) as handle:
                body = handle.read(left + 1)
        except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError) as err:
            raise InputFileError(f"{path}: {name} cannot be unpacked ({err})") from None
        if len(body) > left:
            raise InputFileError(f"{path}: unpacks to more than the {_size(unpacked)} this file may hold ({name})")
        left -= len(body)
        arrays[name] = parse_npy(body, f"{path}: {name}", text=text)
    return arrays


#: Pictures larger than this are refused before they are decoded (the tools draw well under 4 million pixels).
MAX_PICTURE_PIXELS = 50_000_000


def read_png(path: str | os.PathLike, limit: int = 256 * MiB, max_pixels: int = MAX_PICTURE_PIXELS) -> np.ndarray:
    """The PNG picture at ``path`` as an array of 0-1 colours (rows, columns, channels), as matplotlib shows one. Its
    header is read first: a file that is not PNG, or one whose pixels would exceed ``max_pixels``, is refused
    before anything is decoded (a small file can hold a picture of gigabytes)."""
    import struct
    import zlib

    data = read_bytes(path, limit)
    if data[:8] != b"\x89PNG\r\n\x1a\n" or data[12:16] != b"IHDR" or len(data) < 33:
        raise InputFileError(f"{path}: not a PNG picture")
    width, height = struct.unpack(">II", data[16:24])
    if width * height > max_pixels:
        raise InputFileError(f"{path}: a picture of {width:,} x {height:,} pixels, more than the {max_pixels:,} it may hold")
    try:
        from PIL import Image

        with Image.open(io.BytesIO(data), formats=["PNG"]) as picture:
            picture.load()
            array = np.asarray(picture.convert("RGBA" if "A" in picture.getbands() else "RGB"))
    except (OSError, ValueError, SyntaxError, zlib.error) as err:  # PIL's words for a damaged file
        raise InputFileError(f"{path}: not a readable PNG picture ({err})") from None
    return array.astype(np.float32) / 255.0


def _not_a_file(path: Path) -> str | None:
    """What stands at ``path`` if it is something a file written there would replace but must not: a folder, a
    device, a FIFO or a socket (a regular file, a symbolic link, or nothing at all is fine)."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return None
    if stat.S_ISREG(mode) or stat.S_ISLNK(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a folder, expected an output file name"
    kind = "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "a socket"
    return f"is {kind}, not a regular file: refusing to replace it"


def check_output(path: str | os.PathLike) -> Path:
    """Fail now, as writing would, if ``path`` cannot be written: something other than a regular file stands there
    (a folder, a device, a FIFO, a socket), its folder does not exist or is a file, a name is too long, or the folder
    is not writable. Nothing is created."""
    path = Path(path)
    limit = os.pathconf("/", "PC_NAME_MAX") if hasattr(os, "pathconf") else 255
    if any(len(os.fsencode(part)) > limit for part in path.parts):
        raise InputFileError(f"{path}: file name too long")
    try:
        problem = _not_a_file(path)
        if problem:
            raise InputFileError(f"{path}: {problem}")
        folder = path.parent
        if not folder.exists():
            if folder.is_symlink():  # a dangling link where a folder should be
                raise InputFileError(f"{path}: {folder} is a broken symbolic link")
            raise InputFileError(f"{path}: no such folder {folder} (make it first)")
        if not folder.is_dir():
            raise InputFileError(f"{path}: {folder} is a file, not a folder")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise InputFileError(f"{path}: permission denied (cannot write in {folder})")
        # The access check answers yes to the superuser and knows nothing of special file systems (/proc, a read-only
        # mount): a file made and removed again is the one sure test.
        probe = folder / f".write-probe-{uuid.uuid4().hex[:12]}"
        try:
            os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        except OSError as err:
            raise InputFileError(f"{path}: cannot write in {folder} ({err.strerror.lower()})") from None
        os.unlink(probe)
    except OSError as err:
        raise path_error(path, err, writing=True) from None
    return path


def _resolved(path: Path) -> Path | None:
    try:
        return path.resolve()
    except (OSError, RuntimeError):  # a link loop: it names nothing that could be read
        return None


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


def check_not_an_input(
    output: str | os.PathLike, inputs: Iterable[str | os.PathLike], *, folder: bool = False, replaced: bool = False
) -> None:
    """Fail now if writing ``output`` could replace one of ``inputs``: it is the same file or folder (by path or by
    inode: a hard link, a symbolic link to it), or an existing file inside an input folder; an output ``folder``
    that may be ``replaced`` whole (``--overwrite``) also may not hold an input. A new file in an input folder is
    allowed (it replaces nothing)."""
    target = Path(output)
    resolved = _resolved(target)
    if resolved is None:  # a link loop names nothing an input could be
        return
    for given in inputs:
        source = Path(given)
        if not os.path.lexists(source):
            continue
        source_resolved = _resolved(source)
        if source_resolved is None:
            continue
        if _same_file(target, source) or resolved == source_resolved:
            raise InputFileError(f"{target}: is also an input of this command ({source}); writing it would replace it")
        if source.is_dir() and resolved.is_relative_to(source_resolved) and os.path.lexists(target):
            raise InputFileError(
                f"{target}: lies in {source}, which this command reads; writing it would replace a file there (write "
                "elsewhere, or remove it first)"
            )
        if folder and replaced and source_resolved.is_relative_to(resolved):
            raise InputFileError(f"{target}: holds {source}, an input of this command; writing there could replace it")


def atomic_write(path: str | os.PathLike, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder, then rename it into place.

    Readers see either the old file or the complete new one. On any error the temporary file is removed and an
    existing file at ``path`` is left untouched. Missing parent folders are created (user-given paths are checked
    first by :func:`check_output`, which refuses them). A symbolic link at ``path`` is replaced by the file, never
    written through; a folder, device, FIFO or socket there is refused, never replaced.
    """
    path = Path(path)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    # A name in the same folder keeps os.replace on one file system (rename is only atomic there); "x" mode makes
    # the file with the user's umask, unlike mkstemp's 0600.
    tmp = path.with_name(f".{path.name[:200]}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        problem = _not_a_file(path)
        if problem:
            raise InputFileError(f"{path}: {problem}")
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "xb") as handle:
            handle.write(payload)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except OSError as err:
        if tmp.parent.is_dir():
            tmp.unlink(missing_ok=True)
        raise path_error(path, err, writing=True) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_table(stem: str | os.PathLike, report: Any, markdown: str) -> tuple[Path, Path]:
    """A result table in its two forms, ``STEM.json`` (``report``, indented) and ``STEM.md`` (``markdown`` as
    given), each written whole by :func:`atomic_write`. The suffixes are added to the stem's name, never put in
    place of a part after a dot (``results/v1.2`` gives ``v1.2.json``)."""
    stem = Path(stem)
    return (
        atomic_write(stem.with_name(stem.name + ".json"), json.dumps(report, indent=1) + "\n"),
        atomic_write(stem.with_name(stem.name + ".md"), markdown),
    )


#: The largest weight a network takes (the largest 32-bit float).
MAX_WEIGHT = float(np.finfo(np.float32).max)
#: Weight files larger than this are refused before they are read (a 52-60-26 network takes 38 KB).
MAX_WEIGHTS_BYTES = 64 * MiB


def read_weights(path: str | os.PathLike, expected: int, network: str) -> np.ndarray:
    """Read a flat vector of ``expected`` finite numbers (the weights of ``network``, named in errors) from ``.npy``
    or ``.json``; raise ValueError naming the file and the problem otherwise."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npy":
        data = read_npy(path, MAX_WEIGHTS_BYTES)
    elif suffix == ".json":
        data = read_json(path, MAX_WEIGHTS_BYTES)
        if isinstance(data, dict):
            if "weights" not in data:
                raise ValueError(f"{path}: expected a list of numbers or an object with a 'weights' list")
            data = data["weights"]
        if not isinstance(data, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in data):
            raise ValueError(f"{path}: weights must be a flat list of numbers")
        try:
            data = np.asarray(data, dtype=np.float64)
        except OverflowError:  # an integer too large for a float
            raise ValueError(f"{path}: a weight is too large to be a number") from None
    else:
        raise ValueError(f"{path}: unknown weights format {path.suffix!r}; use .npy or .json")
    if data.ndim != 1 or data.dtype.kind not in "iuf":
        raise ValueError(f"{path}: expected a 1-D array of numbers, got shape {data.shape} of {data.dtype}")
    if len(data) != expected:
        raise ValueError(f"{path}: holds {len(data)} weights, but {network} has {expected}")
    if not np.isfinite(data).all():
        raise ValueError(f"{path}: weights contain NaN or infinity")
    if len(data) and np.abs(data).max() > MAX_WEIGHT:
        # The networks compute in 32-bit floats, where such a weight is infinite.
        raise ValueError(f"{path}: a weight of {np.abs(data).max():g} is past the {MAX_WEIGHT:g} 32-bit floats can hold")
    return data.astype(np.float64)

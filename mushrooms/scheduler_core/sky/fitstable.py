"""Stream the rows of a FITS binary table (plain or gzipped) in bounded memory.

Why by hand: astropy.io.fits reads a binary table's data in one piece (it
memory-maps a plain file, and reads a gzipped one whole: ``BinTableHDU``
has no ``section`` for rows, unlike images), so a flat NSIDE 2048 map with
four double columns costs its 1.6 GB unpacked size, and a gzip bomb costs
whatever it unpacks to.  Here astropy parses each *header*
(:meth:`astropy.io.fits.Header.fromstring`, its own card parser) and the
fixed-width rows are read with NumPy from the (gzip) stream, a chunk of rows
at a time, as the dtype the header's ``TFORMn`` cards declare.

Before any data is read the header is held to what it can mean: a binary
table extension (``XTENSION = 'BINTABLE'``, ``BITPIX = 8``, ``NAXIS = 2``,
``GCOUNT = 1``), whose row width ``NAXIS1`` is the sum of its columns'
``TFORMn`` widths; the declared table (``NAXIS1 x NAXIS2``) must fit in the
bytes given (a plain file's size; 1032 x a gzip's size, deflate's largest
ratio).  Reading stops at the declared size; what follows the table must be
its zero padding and then nothing, or another HDU (never read), else the
file is refused: a gzip that unpacks past its declared table is a bomb.
``tests/scheduler/test_skymap_stream.py`` checks what comes out against
ligo.skymap's reading (astropy's ``Table.read``) of the same files, for
one and 1024 pixels a row, float32 and float64, unsigned UNIQ, plain and gzip.
"""

from __future__ import annotations

import gzip
import hashlib
import re
import warnings
import zlib
from dataclasses import dataclass
from typing import Any, BinaryIO, Iterator

import numpy as np

from ..errors import SkyMapError

__all__ = ["BinaryTable", "open_table", "BLOCK", "MAX_DEFLATE_RATIO"]

#: FITS block (bytes): headers and data are padded to multiples of it.
BLOCK = 2880
#: Largest ratio of unpacked to packed size deflate can reach (RFC 1951: a
#: 258-byte match coded in 2 bits at best, 258 x 8 / 2 = 1032); a header
#: declaring more than 1032 x the gzip's size cannot be honest.
MAX_DEFLATE_RATIO = 1032
#: Most header blocks we read before an END card (real sky maps: 1-3).
MAX_HEADER_BLOCKS = 64
#: Largest primary data array we skip to reach the table (LVK maps: none).
MAX_PRIMARY_DATA = 1 << 20

#: TFORM letter -> (bytes per element, NumPy big-endian type or None when not numeric).
_TFORM = {"L": (1, None), "X": (0, None), "B": (1, ">u1"), "I": (2, ">i2"), "J": (4, ">i4"),
          "K": (8, ">i8"), "A": (1, None), "E": (4, ">f4"), "D": (8, ">f8"), "C": (8, None),
          "M": (16, None), "P": (8, None), "Q": (16, None)}
_TFORM_RE = re.compile(r"^\s*(\d*)\s*([LXBIJKAEDCMPQ])")


class _HashingReader:
    """A binary file object that feeds a SHA-256 with every byte read through it."""

    def __init__(self, fh: BinaryIO):
        self._fh = fh
        self.sha = hashlib.sha256()
        self.mode = "rb"

    def read(self, n: int = -1) -> bytes:
        data = self._fh.read(n)
        self.sha.update(data)
        return data

    def drain(self) -> None:
        """Read (and hash) what is left."""
        while self.read(1 << 20):
            pass


@dataclass
class BinaryTable:
    """The first binary-table extension of a FITS file, its rows still unread.

    Attributes
    ----------
    header : astropy.io.fits.Header
        The extension's header.
    names : tuple of str
        Column names (``TTYPEn``, upper case).
    repeats : dict of str to int
        Elements per row of each numeric column (``1024`` for ``TFORM = '1024E'``).
    rows : int
        ``NAXIS2``.
    row_dtype : numpy.dtype
        One row (big-endian, numeric columns named, the rest padding).
    """

    header: object
    names: tuple[str, ...]
    repeats: dict[str, int]
    rows: int
    row_dtype: np.dtype
    _stream: "_Counting"
    _hashing: _HashingReader | None
    _name: str
    _data_bytes: int
    _heap_bytes: int
    _unsigned: frozenset[str]
    _size: int | None
    _gzipped: bool
    _offset: int

    def check_room(self) -> None:
        """Refuse a table larger than the input bytes can hold (before reading any of it).

        A plain file must hold the declared table (``NAXIS1 x NAXIS2 +
        PCOUNT`` bytes) after its headers; a gzip cannot unpack to more than
        1032 times its size.

        Raises
        ------
        SkyMapError
            Naming the declared and the possible sizes.
        """
        if self._size is None:
            return
        data = self._data_bytes + self._heap_bytes
        room = self._size * MAX_DEFLATE_RATIO if self._gzipped else self._size - self._offset
        if data > room:
            what = f"a {self._size}-byte gzip can unpack to (x{MAX_DEFLATE_RATIO})" if self._gzipped else \
                f"the {self._size}-byte file holds after its headers ({room})"
            raise SkyMapError(f"truncated or forged sky map {self._name}: its table declares {data} bytes "
                              f"({self.rows} rows of {self.row_dtype.itemsize}), more than {what}")

    def iter_rows(self, chunk_rows: int) -> Iterator[np.ndarray]:
        """The table's rows, ``chunk_rows`` at a time (structured arrays, big-endian).

        Raises
        ------
        SkyMapError
            When the data end before the declared ``NAXIS2`` rows.
        """
        chunk_rows = max(int(chunk_rows), 1)
        width = self.row_dtype.itemsize
        done = 0
        while done < self.rows:
            n = min(chunk_rows, self.rows - done)
            buf = self._stream.read(n * width)
            if len(buf) < n * width:
                raise SkyMapError(f"truncated sky map {self._name}: the table declares {self.rows} rows of "
                                  f"{width} bytes, the data end after {done + len(buf) // width}")
            done += n
            yield np.frombuffer(buf, dtype=self.row_dtype)

    def column(self, rows: np.ndarray, name: str, dtype: type = np.float64) -> np.ndarray:
        """One column of a chunk of rows, flattened (row-major: a row's elements in order), as ``dtype``."""
        values = rows[name].reshape(-1)
        if name in self._unsigned:  # stored signed with TZERO = 2^(n-1): flip the sign bit
            native = values.astype(values.dtype.newbyteorder("="))
            kind = np.dtype(f"u{native.itemsize}")
            values = native.view(kind) ^ np.array(1 << (8 * native.itemsize - 1), dtype=kind)
        return values.astype(dtype)

    def finish(self) -> str:
        """Check what follows the table and return the SHA-256 (hex) of the input bytes ("" if not hashed).

        After the table (and its heap) only zero padding to a block boundary
        may follow, then either the end of the file or another extension
        (``XTENSION``), which is not read.

        Raises
        ------
        SkyMapError
            When other bytes follow (a gzip grown past its declared table).
        """
        left = self._heap_bytes
        while left > 0:
            got = self._stream.read(min(left, 1 << 20))
            if not got:
                raise SkyMapError(f"truncated sky map {self._name}: the table's heap ends early")
            left -= len(got)
        end = self._data_bytes + self._heap_bytes
        pad = (-end) % BLOCK
        tail = self._stream.read(pad + BLOCK)
        padding, after = tail[:pad], tail[pad:]
        if padding.strip(b"\0") or (after and not after.startswith(b"XTENSION")):
            raise SkyMapError(f"sky map {self._name}: more bytes follow its declared table ({end} bytes) "
                              "than padding or another FITS extension: refused")
        if self._hashing is None:
            return ""
        self._hashing.drain()  # the rest of the input as given (packed, for a gzip): hashed, not unpacked
        return self._hashing.sha.hexdigest()


def _read_exact(fh: BinaryIO, n: int) -> bytes:
    """Up to ``n`` bytes (fewer only at the end of the stream)."""
    parts, left = [], n
    while left > 0:
        got = fh.read(left)
        if not got:
            break
        parts.append(got)
        left -= len(got)
    return parts[0] if len(parts) == 1 else b"".join(parts)


def _header(read, name: str, what: str) -> object:
    """Read header blocks up to the END card; astropy parses them."""
    from astropy.io import fits

    blocks = []
    for _ in range(MAX_HEADER_BLOCKS):
        block = read(BLOCK)
        if len(block) < BLOCK:
            if not blocks and not block:
                raise SkyMapError(f"sky map {name} has no HEALPix table extension (the file ends after the "
                                  "primary header)" if what == "extension" else f"sky map is empty: {name}")
            raise SkyMapError(f"truncated sky map {name}: the {what} header ends early")
        blocks.append(block)
        cards = [block[i:i + 80] for i in range(0, BLOCK, 80)]
        if any(c.rstrip() == b"END" for c in cards):
            break
    else:
        raise SkyMapError(f"sky map {name}: no END card in the first {MAX_HEADER_BLOCKS} blocks of its {what} header")
    raw = b"".join(blocks)
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        raise SkyMapError(f"sky map {name}: its {what} header is not ASCII text") from None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return fits.Header.fromstring(text)
        except Exception as exc:  # astropy raises several types for bad cards
            raise SkyMapError(f"sky map {name}: unreadable {what} header ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None


def _int(header, key: str, name: str, lo: int = 0) -> int:
    v = header.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise SkyMapError(f"sky map {name}: header keyword {key} must be an integer >= {lo}, got {v!r}")
    return v


def open_table(fh: BinaryIO, name: str, size: int | None, hashed: bool) -> BinaryTable:
    """Parse the headers of a FITS file up to its first binary table.

    Parameters
    ----------
    fh : file object
        The input bytes (plain FITS or gzip), positioned at the start.
    name : str
        For messages.
    size : int or None
        Size (bytes) of the input, when known: the declared table must fit in it
        (x 1032 for a gzip).
    hashed : bool
        Hash the input bytes as they are read (:meth:`BinaryTable.finish` returns the digest).

    Returns
    -------
    BinaryTable

    Raises
    ------
    SkyMapError
        Not FITS, broken gzip, no binary table, a header whose declared
        table its columns or the input bytes cannot hold.
    """
    from .sniff import FITS_MAGIC, GZIP_MAGIC

    hashing = _HashingReader(fh) if hashed else None
    source: BinaryIO = hashing if hashing is not None else fh  # type: ignore[assignment]
    first = _read_exact(source, 2)
    gzipped = first == GZIP_MAGIC
    joined = _Rejoined(first, source)
    stream = _Counting(gzip.GzipFile(fileobj=joined, mode="rb") if gzipped else joined, name)  # type: ignore[arg-type]
    start = stream.read(len(FITS_MAGIC))
    if not start.startswith(FITS_MAGIC):
        if not start:
            raise SkyMapError(f"sky map is empty: {name}")
        raise SkyMapError(f"not a FITS file: {name}" + (" (a gzip of something else)" if gzipped else ""))
    stream.unread(start)
    _skip_primary(stream, name)
    header = _header(stream.read, name, "extension")
    xt = str(header.get("XTENSION", "")).strip().upper()
    if xt != "BINTABLE":
        raise SkyMapError(f"sky map {name}: its first extension is {xt or 'not an extension'}, "
                          "not a HEALPix binary table")
    if header.get("BITPIX") != 8 or header.get("NAXIS") != 2 or header.get("GCOUNT", 1) != 1:
        raise SkyMapError(f"sky map {name}: a binary table needs BITPIX = 8, NAXIS = 2, GCOUNT = 1")
    width = _int(header, "NAXIS1", name, 1)
    rows = _int(header, "NAXIS2", name, 1)
    heap = _int(header, "PCOUNT", name) if "PCOUNT" in header else 0
    nfields = _int(header, "TFIELDS", name, 1)
    if nfields > 999:
        raise SkyMapError(f"sky map {name}: TFIELDS {nfields} exceeds FITS's 999")
    names, formats, offsets, repeats, unsigned = _columns(header, name, nfields, width)
    row_dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": width})
    return BinaryTable(header=header, names=tuple(names), repeats=repeats, rows=rows, row_dtype=row_dtype,
                       _stream=stream, _hashing=hashing, _name=name, _data_bytes=width * rows, _heap_bytes=heap,
                       _unsigned=frozenset(unsigned), _size=size, _gzipped=gzipped, _offset=stream.count)


def _skip_primary(stream: Any, name: str) -> None:
    """Read the primary header and skip its (small) data array; a sky map's primary HDU has none."""
    primary = _header(stream.read, name, "primary")
    if primary.get("SIMPLE") is not True:
        raise SkyMapError(f"not a FITS file: {name} (SIMPLE is not T)")
    naxis = _int(primary, "NAXIS", name)
    bitpix = primary.get("BITPIX", 8)
    n_primary = 0
    if naxis:
        n_primary = abs(int(bitpix)) // 8 if isinstance(bitpix, int) else 1
        for i in range(1, naxis + 1):
            n_primary *= _int(primary, f"NAXIS{i}", name)
    if n_primary > MAX_PRIMARY_DATA:
        raise SkyMapError(f"sky map {name}: its primary array declares {n_primary} bytes (a sky map's has none)")
    if n_primary:
        stream.read(n_primary + (-n_primary) % BLOCK)


def _columns(header: Any, name: str, nfields: int, width: int
             ) -> tuple[list[str], list[np.dtype], list[int], dict[str, int], set[str]]:
    """The table's readable columns from its TFORM/TTYPE cards: names, dtypes, byte offsets, repeats, unsigned."""
    names: list[str] = []
    formats: list[np.dtype] = []
    offsets: list[int] = []
    repeats: dict[str, int] = {}
    unsigned: set[str] = set()
    used = 0
    for i in range(1, nfields + 1):
        tform = str(header.get(f"TFORM{i}", ""))
        m = _TFORM_RE.match(tform)
        if m is None:
            raise SkyMapError(f"sky map {name}: column {i} has no valid TFORM ({tform!r})")
        repeat = int(m.group(1)) if m.group(1) else 1
        letter = m.group(2)
        nbytes_each, numpy_type = _TFORM[letter]
        col = str(header.get(f"TTYPE{i}", f"COL{i}")).strip().upper()
        if numpy_type is not None and repeat > 0 and col not in repeats:
            scale, zero = header.get(f"TSCAL{i}", 1), header.get(f"TZERO{i}", 0)
            if zero and letter in "IJK" and zero == 2 ** (8 * nbytes_each - 1) and scale == 1:
                unsigned.add(col)  # FITS's unsigned integers (old ligo.skymap UNIQ columns)
            elif scale != 1 or zero != 0:
                raise SkyMapError(f"sky map {name}: column {col} is scaled (TSCAL/TZERO), not supported")
            names.append(col)
            formats.append(np.dtype(numpy_type) if repeat == 1 else np.dtype((numpy_type, (repeat,))))
            offsets.append(used)
            repeats[col] = repeat
        used += (repeat + 7) // 8 if letter == "X" else repeat * nbytes_each
    if used != width:
        raise SkyMapError(f"sky map {name}: rows of NAXIS1 = {width} bytes, but its columns' TFORMs add up "
                          f"to {used}: refused")
    return names, formats, offsets, repeats, unsigned


class _Rejoined:
    """The bytes already read from a stream, then the rest of it."""

    mode = "rb"

    def __init__(self, first: bytes, rest: BinaryIO):
        self._first, self._rest = first, rest

    def read(self, n: int = -1) -> bytes:
        got, self._first = (self._first, b"") if n < 0 or n >= len(self._first) else \
            (self._first[:n], self._first[n:])
        if n < 0:
            return got + self._rest.read()
        return got if len(got) == n else got + self._rest.read(n - len(got))


class _Counting:
    """The unpacked stream: exact reads, a byte count, one-line errors for broken gzip."""

    def __init__(self, fh: BinaryIO, name: str):
        self._fh, self._name, self.count, self._back = fh, name, 0, b""

    def unread(self, data: bytes) -> None:
        self._back, self.count = data + self._back, self.count - len(data)

    def read(self, n: int) -> bytes:
        head, self._back = self._back[:n], self._back[n:]
        try:
            got = head + _read_exact(self._fh, n - len(head)) if n > len(head) else head
        except (OSError, EOFError, zlib.error) as exc:  # BadGzipFile is an OSError
            raise SkyMapError(f"broken gzip in sky map {self._name}: {exc}") from None
        self.count += len(got)
        return got

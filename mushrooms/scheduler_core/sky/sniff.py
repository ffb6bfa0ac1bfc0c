"""Is this a FITS file? The one rule the whole package uses.

A FITS file starts with the card ``SIMPLE  =`` (FITS 4.0, section 4.4.1.1:
the keyword in bytes 1-8, ``=`` in byte 9); a gzipped one starts with the
gzip magic ``1f 8b`` and unpacks to such a start.  The notice parser, the
pipeline's bare-map path, ``mushrooms trigger`` and the sky-map reader all
ask :func:`sniff_fits` (they once used four different rules, and a file
named ``*.gz`` counted as a sky map whatever it held).
"""

from __future__ import annotations

import zlib

__all__ = ["FITS_MAGIC", "GZIP_MAGIC", "sniff_fits", "is_fits"]

#: The first nine bytes of every FITS file.
FITS_MAGIC = b"SIMPLE  ="
#: The first two bytes of every gzip member (RFC 1952).
GZIP_MAGIC = b"\x1f\x8b"


def sniff_fits(head: bytes) -> str | None:
    """What the first bytes of a file say it is.

    Parameters
    ----------
    head : bytes
        The start of the file (a few hundred bytes are enough for a gzip:
        only its first nine unpacked bytes are looked at).

    Returns
    -------
    str or None
        ``"fits"`` (plain FITS), ``"gzip"`` (a gzip whose content starts as
        FITS, or one too broken to unpack: the reader then says "broken
        gzip") or None (anything else, including a gzip that unpacks to
        something else, e.g. a doubly packed file).
    """
    head = bytes(head[:65536])
    if head.startswith(FITS_MAGIC):
        return "fits"
    if head.startswith(GZIP_MAGIC):
        try:
            start = zlib.decompressobj(31).decompress(head, len(FITS_MAGIC))
        except zlib.error:
            return "gzip"  # broken: the reader's one line says how
        return "gzip" if len(start) < len(FITS_MAGIC) or start.startswith(FITS_MAGIC) else None
    return None


def is_fits(head: bytes) -> bool:
    """True when :func:`sniff_fits` recognises ``head`` (plain or gzipped FITS)."""
    return sniff_fits(head) is not None

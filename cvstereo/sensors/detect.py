"""Tell the event format and sync-bit polarity of an eDVS stream from its first bytes.

Each candidate (format x sync bit) decodes the sample; the true one explains (nearly) every byte, the
wrong ones lose most bytes to resynchronisation. Where several explain the sample about equally (E0 has
no timestamp to check, so the bytes of a timestamped format often pass as E0 for a while), the one with
the most structure per event wins.

>>> from cvstereo.model.events import make_events
>>> from cvstereo.sensors.protocol import ProtocolSettings, encode_events
>>> ev = make_events(range(0, 40_000, 100), [3] * 400, [5] * 400, [1, 0] * 200)
>>> detect_protocol(encode_events(ev, ProtocolSettings(event_format="E3"))).describe()
'E3, sync bit set'
"""

from __future__ import annotations

from dataclasses import dataclass

from cvstereo.errors import SensorError
from cvstereo.sensors.protocol import FORMAT_NUMBERS, FORMATS, ProtocolSettings

__all__ = ["DETECT_BYTES", "DETECT_MAX_BYTES", "DETECT_MIN_BYTES", "FIT_THRESHOLD", "TIE_MARGIN", "Detection",
           "ProtocolMismatchError", "check_protocol", "detect_protocol", "explained_share", "rank_protocols"]

#: Bytes looked at before deciding (about 2.6 ms of a saturated 4 Mbaud link, 256 events of E2).
DETECT_BYTES = 1024

#: Fewest bytes from which a decision is attempted (at a pause or the end of the stream).
DETECT_MIN_BYTES = 64

#: Bytes after which a stream that fits no format is refused.
DETECT_MAX_BYTES = 65_536

#: Share of the sample the best candidate must explain.
FIT_THRESHOLD = 0.9

#: Candidates within this share of the best count as equally good (then the most structured wins).
TIE_MARGIN = 0.02


class ProtocolMismatchError(SensorError):
    """The stream does not fit the protocol settings given (or no settings at all)."""


@dataclass(frozen=True)
class Detection:
    """What a sample of a stream looks like."""

    event_format: str
    sync_bit_set: bool
    explained: float  # share of the sample's bytes inside events
    sample_bytes: int

    def describe(self) -> str:
        return f"{self.event_format}, sync bit {'set' if self.sync_bit_set else 'clear'}"


def explained_share(data: bytes, event_format: str, sync_bit_set: bool) -> float:
    """Share of ``data`` that decodes into events with this format and sync bit (0 for no data)."""
    from cvstereo.sensors.decoder import StreamDecoder

    if not data:
        return 0.0
    dec = StreamDecoder(ProtocolSettings(event_format=event_format, sync_bit_set=sync_bit_set))
    dec.decode(data, final=True)
    # An event cut off by the end of the sample is neither evidence for nor against.
    whole = len(data) - dec.tail_bytes
    return dec.bytes_decoded / whole if whole > 0 else 0.0


def rank_protocols(data: bytes) -> list[Detection]:
    """Every candidate with its share, best first (ties broken towards the more structured format)."""
    cands = [Detection(f, s, explained_share(data, f, s), len(data)) for f in FORMATS for s in (True, False)]
    best = max(c.explained for c in cands)
    return sorted(cands, key=lambda c: (c.explained < best - TIE_MARGIN, -FORMATS[c.event_format].max_size,
                                        -c.explained, not c.sync_bit_set))


def detect_protocol(data: bytes) -> Detection | None:
    """The format and sync bit the bytes fit, or None when none explains ``FIT_THRESHOLD`` of them."""
    ranked = rank_protocols(data)
    return ranked[0] if ranked[0].explained >= FIT_THRESHOLD else None


def check_protocol(data: bytes, settings: ProtocolSettings, *, auto_format: bool, auto_sync: bool,
                   name: str, final: bool = False, pause: bool = False) -> tuple[ProtocolSettings, str] | None:
    """Settings to decode with, and a note of what was detected; None while more bytes are needed.

    Decides once ``DETECT_BYTES`` have come, at a pause in the stream (``pause``) from ``DETECT_MIN_BYTES``,
    and at its end (``final``) from whatever there is.

    Raises
    ------
    ProtocolMismatchError
        An explicit setting contradicts the stream, or (``auto``) no format fits ``DETECT_MAX_BYTES``.
    """
    n = len(data)
    if n < DETECT_MIN_BYTES or (n < DETECT_BYTES and not (final or pause)):
        if not final:
            return None
        return settings, f"{settings.event_format}, sync bit {'set' if settings.sync_bit_set else 'clear'} " \
                         f"(assumed: only {n} bytes, too few to detect)"
    ranked = rank_protocols(data)
    best = ranked[0]
    if best.explained < FIT_THRESHOLD:
        if n < DETECT_MAX_BYTES and not final:
            return None
        if auto_format or auto_sync:
            raise ProtocolMismatchError(
                f"{name} sensor: the first {n} bytes do not look like eDVS events in any format (the best, "
                f"{best.describe()}, explains {best.explained:.0%} of them); check the baud rate and the cable, "
                "or give --event-format and --sync-bit to record anyway.")
        return settings, f"{settings.event_format} as given (the stream fits no format: {best.explained:.0%} " \
                         "explained by the best)"
    fits = [c for c in ranked if c.explained >= FIT_THRESHOLD
            and (auto_format or c.event_format == settings.event_format)
            and (auto_sync or c.sync_bit_set == settings.sync_bit_set)]
    if not fits or fits[0].explained < best.explained - TIE_MARGIN:
        given = []
        if not auto_format:
            given.append(f"--event-format {settings.event_format}")
        if not auto_sync:
            given.append(f"--sync-bit {'set' if settings.sync_bit_set else 'clear'}")
        raise ProtocolMismatchError(
            f"{name} sensor: stream looks like {best.describe()} ({best.explained:.0%} of the first {n} bytes "
            f"fit), not what {' '.join(given)} says; give the matching value or 'auto'.")
    got = fits[0]
    chosen = ProtocolSettings(event_format=got.event_format, sync_bit_set=got.sync_bit_set,
                              off_bit_set=settings.off_bit_set,
                              numbering=settings.numbering if got.event_format in FORMAT_NUMBERS[settings.numbering]
                              else "current",
                              line_ending=settings.line_ending, commands=settings.commands)
    how = "detected" if (auto_format or auto_sync) else "checked"
    return chosen, f"{got.describe()} ({how} from the first {n} bytes)"

"""Live sensors: the eDVS128 serial protocol, streaming decoder, one board, two boards on one clock, a virtual
board on a pseudo-terminal; DV cameras and DV network streams; any two merged into stereo packets; and an
append-only journal for recording."""

import importlib

# Submodules are imported on first use, so that `cvstereo --help` does not load numba for the decoder.
_EXPORTS = {
    "StreamDecoder": "decoder", "EDVS": "edvs", "Chunk": "edvs", "Journal": "journal", "read_journal": "journal",
    "FORMATS": "protocol", "Commands": "protocol", "ProtocolSettings": "protocol", "encode_events": "protocol",
    "link_event_rate": "protocol", "StereoEDVS": "stereo", "StereoRig": "stereo",
    "DVSource": "dvlive", "StereoSettings": "stereo", "VirtualEDVS": "virtual",
    "VirtualClock": "virtual", "ProtocolMismatchError": "detect", "detect_protocol": "detect",
}


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"cvstereo.sensors.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module 'cvstereo.sensors' has no attribute {name!r}")


__all__ = [
    "EDVS", "FORMATS", "Chunk", "Commands", "DVSource", "Journal", "ProtocolMismatchError", "ProtocolSettings",
    "StereoEDVS", "StereoRig", "StereoSettings", "StreamDecoder", "VirtualClock", "VirtualEDVS", "detect_protocol",
    "encode_events", "link_event_rate", "read_journal",
]

"""Live eDVS128 sensors: serial protocol, streaming decoder, one board, two boards on one clock, a virtual
board on a pseudo-terminal, and an append-only journal for recording."""

from cvstereo.sensors.decoder import StreamDecoder
from cvstereo.sensors.edvs import EDVS, Chunk
from cvstereo.sensors.journal import Journal, read_journal
from cvstereo.sensors.protocol import FORMATS, Commands, ProtocolSettings, encode_events, link_event_rate
from cvstereo.sensors.stereo import StereoEDVS, StereoSettings
from cvstereo.sensors.virtual import VirtualEDVS

__all__ = [
    "EDVS", "FORMATS", "Chunk", "Commands", "Journal", "ProtocolSettings", "StereoEDVS", "StereoSettings",
    "StreamDecoder", "VirtualEDVS", "encode_events", "link_event_rate", "read_journal",
]

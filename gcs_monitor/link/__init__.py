"""Bytes in, decoded MAVLink messages out: transports, pymavlink decoding, link statistics."""

from gcs_monitor.link.decode import Decoder, decode_all, split_by_sysid
from gcs_monitor.link.stats import LinkCounters, LinkStats
from gcs_monitor.link.transports import (
    SerialSource,
    Source,
    SourceError,
    TcpSource,
    TlogSource,
    UdpSource,
    ZenohSource,
    open_source,
)

__all__ = ["Decoder", "LinkCounters", "LinkStats", "SerialSource", "Source", "SourceError",
           "TcpSource", "TlogSource", "UdpSource", "ZenohSource", "decode_all", "open_source",
           "split_by_sysid"]

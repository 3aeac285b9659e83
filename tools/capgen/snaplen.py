"""Captures whose packets the capture cut (snaplen): each is one of the
project's captures with some frames cut short, their length on the wire
kept, so what they hold is known."""
from . import profinet
from .pcap import EPOCH, Capture
from .registry import capture


def snapped(cap, snaplen, frames=None):
    """cap with the frames numbered in `frames` (1-based; None: all) cut to
    snaplen bytes, as a capture with that snaplen keeps them."""
    out = Capture(cap.linktype, cap.snaplen)
    for i, (ts, data, orig_len) in enumerate(cap.records, 1):
        if frames is None or i in frames:
            data = data[:snaplen]
        out.add(ts - EPOCH, data, orig_len)
    return out


@capture("snaplen_connect.pcap",
         "mcmb2_duplex_connect.pcap with every frame cut at 96 bytes (editcap -s 96): the Connect request and "
         "response are cut, the cyclic frames whole; the layout is inferred from them")
def connect():
    return snapped(profinet.duplex_connect(), 96)


@capture("snaplen_mcmb2.pcap",
         "mcmb2_duplex_watchdog.pcap (its Connect whole) with the cyclic frames 11..30 cut at 40 bytes, inside "
         "both watchdog stalls: the watchdogs survive, the data does not")
def mcmb2():
    return snapped(profinet.duplex_watchdog(), 40, set(range(11, 31)))


@capture("snaplen_eclink_pnio.pcap",
         "eclink_pnio_connect.pcap (its Connect whole) with the cyclic frames 31..60 cut at 60 bytes: image bytes "
         "0..39 (input) and 0..38 (output) survive, with every handshake counter")
def eclink_pnio():
    return snapped(profinet.eclink_connect(), 60, set(range(31, 61)))

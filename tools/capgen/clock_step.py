"""Captures whose time steps back 2 s in the middle (a clock set back while
capturing, or captures joined): each is one of the project's captures with
every frame from one on 2 s earlier, so the faults it holds are known."""
from . import eclink_modbus, profinet
from .pcap import EPOCH, Capture
from .registry import capture

STEP_S = 2.0


def stepped(cap, frame, by=STEP_S):
    """cap with frames `frame`.. (1-based) moved `by` seconds earlier."""
    out = Capture(cap.linktype, cap.snaplen)
    for i, (ts, data, orig_len) in enumerate(cap.records, 1):
        out.add(ts - EPOCH - (by if i >= frame else 0.0), data, orig_len)
    return out


@capture("clockstep_modbus.pcap",
         "eclink_modbus_faults.pcap with the time stepped back 2 s from frame 24 (the read of the cycle after "
         "the PCI stall): every fault still found, no negative time")
def modbus():
    return stepped(eclink_modbus.faults(), 24)


@capture("clockstep_mcmb2.pcap",
         "mcmb2_duplex_watchdog.pcap with the time stepped back 2 s from frame 20 (inside both watchdog "
         "stalls): both stalls still found, no negative age")
def mcmb2():
    return stepped(profinet.duplex_watchdog(), 20)


@capture("clockstep_eclink_pnio.pcap",
         "eclink_pnio_connect.pcap with the time stepped back 2 s from frame 50 (after the command from RU "
         "that is never acknowledged): the command still found, no negative age")
def eclink_pnio():
    return stepped(profinet.eclink_connect(), 50)

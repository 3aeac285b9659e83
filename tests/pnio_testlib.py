"""PROFINET IO frames for the tests, built from the specifications with
scapy's own layers and independent of tools/capgen.

A device is its list of submodules (slot, subslot, input and output bytes).
In each direction the C-SDU holds, in slot order, for every submodule with
data in that direction its data and then its IOPS, and for every submodule
with data in the other direction its IOCS (the DAP submodules count as
input submodules without data); it is padded with zeros to 40 bytes. The
cyclic frames are scapy ProfinetIO / PNIORealTimeCyclicPDU packets, the
Connect request and response scapy.contrib.pnio_rpc blocks in DCE/RPC over
UDP.

MC-MB2-PN (SP-14-023 section 5.3): uplink header (2 bytes duplex, 8 polled),
the uplink data modules of each terminal largest first (20, 10, 8, 4, 2),
downlink header (2), then per terminal its downlink data modules and its
downlink ASCII modules (40, 20, 10, 8, 4, 2), each run largest first.
EC-Link (TS-0007): slot 1 input image 64 bytes, slot 2 output image 20 or
224 bytes, or none.
"""
import uuid
from dataclasses import dataclass, field

from scapy.contrib.pnio import PNIORealTime_IOxS, PNIORealTimeCyclicDefaultRawData, \
    PNIORealTimeCyclicPDU, ProfinetIO
from scapy.contrib.pnio_rpc import AlarmCRBlockReq, AlarmCRBlockRes, ARBlockReq, ARBlockRes, \
    ExpectedSubmodule, ExpectedSubmoduleAPI, ExpectedSubmoduleBlockReq, ExpectedSubmoduleDataDescription, \
    IOCRAPI, IOCRAPIObject, IOCRBlockReq, IOCRBlockRes, PNIOServiceReqPDU, PNIOServiceResPDU
from scapy.layers.dcerpc import DceRpc4
from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import Ether
from scapy.packet import Raw
from scapy.utils import PcapWriter

DATA_MODULES = (20, 10, 8, 4, 2)
ASCII_MODULES = (40, 20, 10, 8, 4, 2)
GOOD = 0x80
IOXS_GOOD = bytes(PNIORealTime_IOxS(dataState="good"))  # built once: scapy packets are slow to make
CONTROLLER_MAC = "02:00:00:00:00:01"
PNIO_CM = 34964
E010 = ("Fieldbus update failure (E010): no valid terminal data, the IO controller must keep the system in a "
        "safe state")


def largest_first(size, sizes):
    """SP-14-023 5.3: modules for `size` bytes, largest first."""
    out = []
    for m in sizes:
        out += [m] * (size // m)
        size %= m
    assert size == 0, "odd size"
    return out


@dataclass(frozen=True)
class Submodule:
    slot: int
    subslot: int
    inlen: int = 0
    outlen: int = 0


def dap_submodules(count):
    """Slot 0: the DAP itself (subslot 1), then interface and ports (0x8000...)."""
    return [Submodule(0, 1 if i == 0 else 0x8000 + i - 1) for i in range(count)]


def mcmb2_submodules(system, dap, up, data, ascii_, terminals):
    """The submodules of an MC-MB2-PN (section 5.3). up, data, ascii_: bytes of one terminal."""
    sizes = [("in", 2 if system == "duplex" else 8)]
    sizes += [("in", m) for _ in range(terminals) for m in largest_first(up, DATA_MODULES)]
    sizes += [("out", 2)]
    for _ in range(terminals):
        sizes += [("out", m) for m in largest_first(data, DATA_MODULES) + largest_first(ascii_, ASCII_MODULES)]
    subs = dap_submodules(dap)
    for slot, (d, n) in enumerate(sizes, start=1):
        subs.append(Submodule(slot, 1, n if d == "in" else 0, n if d == "out" else 0))
    return subs


def eclink_submodules(dap, outlen):
    subs = dap_submodules(dap) + [Submodule(1, 1, inlen=64)]
    if outlen:
        subs.append(Submodule(2, 1, outlen=outlen))
    return subs


@dataclass
class Device:
    """One IO device and its controller. in_fid: FrameID of the input
    (uplink) frame, out_fid of the output (downlink) frame."""
    subs: list
    mac: str
    in_fid: int
    out_fid: int
    ip: str = "192.168.1.2"
    ctl_mac: str = CONTROLLER_MAC
    ctl_ip: str = "192.168.1.1"
    ar: uuid.UUID = field(default_factory=uuid.uuid4)
    cycle: int = 0
    # The frame layout the controller assigns: order(direction, elements)
    # returns the elements (slot order) in frame order; None: slot order.
    order: object = None

    def _elements(self, direction):
        """[(kind, submodule)] in frame order; kind: "data" (data + IOPS) or "iocs"."""
        out = []
        for s in sorted(self.subs, key=lambda s: (s.slot, s.subslot)):
            mine = (s.outlen > 0) if direction == "out" else (s.outlen == 0)
            out.append(("data" if mine else "iocs", s))
        if self.order:
            got = list(self.order(direction, out))
            assert sorted(got, key=id) == sorted(out, key=id), "order() must permute the elements"
            return got
        return out

    def _length(self, s, direction):
        return s.outlen if direction == "out" else s.inlen

    def offsets(self, direction):
        """[(submodule, frame offset)] of the IO data objects and of the IOCS, and the C-SDU length."""
        objs, iocs, off = [], [], 0
        for kind, s in self._elements(direction):
            if kind == "data":
                objs.append((s, off))
                off += self._length(s, direction) + 1
            else:
                iocs.append((s, off))
                off += 1
        # the IOCR block lists them in slot order, whatever their offsets
        key = lambda p: (p[0].slot, p[0].subslot)  # noqa: E731
        return sorted(objs, key=key), sorted(iocs, key=key), max(off, 40)

    def c_sdu(self, direction, data):
        """The C-SDU as scapy packets; data: {slot: bytes} (missing: zeros)."""
        parts = []
        for kind, s in self._elements(direction):
            n = self._length(s, direction)
            if kind == "data" and n:
                b = bytes(data.get(s.slot, bytes(n)))
                assert len(b) == n, (s, len(b))
                parts.append(b)
            parts.append(IOXS_GOOD)
        raw = b"".join(parts)
        return PNIORealTimeCyclicPDU(data=[PNIORealTimeCyclicDefaultRawData(data=raw)],
                                     padding=bytes(max(0, 40 - len(raw))),
                                     cycleCounter=self.cycle, dataStatus=0x35, transferStatus=0)

    def cyclic(self, direction, data):
        """A cyclic frame: "in" from the device, "out" from the controller."""
        self.cycle = (self.cycle + 32) & 0xFFFF
        src, dst, fid = (self.mac, self.ctl_mac, self.in_fid) if direction == "in" else \
            (self.ctl_mac, self.mac, self.out_fid)
        return Ether(src=src, dst=dst) / ProfinetIO(frameID=fid) / self.c_sdu(direction, data)

    # -- Connect ---------------------------------------------------------------
    def _iocr(self, direction, ref, fid):
        objs, iocs, length = self.offsets(direction)

        def api_objects(pairs):
            return [IOCRAPIObject(SlotNumber=s.slot, SubslotNumber=s.subslot, FrameOffset=o) for s, o in pairs]
        return IOCRBlockReq(IOCRType=1 if direction == "in" else 2, IOCRReference=ref, IOCRProperties_RTClass=2,
                            DataLength=length, FrameID=fid, SendClockFactor=32, ReductionRatio=8,
                            IOCRMulticastMACAdd="00:00:00:00:00:00",
                            APIs=[IOCRAPI(API=0, IODataObjects=api_objects(objs), IOCSs=api_objects(iocs))])

    def _expected_submodules(self):
        """One ExpectedSubmoduleBlockReq with an API entry per slot."""
        apis = []
        for slot in sorted({s.slot for s in self.subs}):
            subs = []
            for s in sorted((s for s in self.subs if s.slot == slot), key=lambda s: s.subslot):
                kind = (1 if s.inlen else 0) + (2 if s.outlen else 0)
                descs = [ExpectedSubmoduleDataDescription(DataDescription=dd, SubmoduleDataLength=n, LengthIOCS=1,
                                                          LengthIOPS=1)
                         for dd, n in ((1, s.inlen), (2, s.outlen)) if n or (dd == 1 and kind == 0)]
                subs.append(ExpectedSubmodule(SubslotNumber=s.subslot, SubmoduleIdentNumber=0x100 + slot,
                                              SubmoduleProperties_Type=kind, DataDescription=descs))
            apis.append(ExpectedSubmoduleAPI(API=0, SlotNumber=slot, ModuleIdentNumber=0x200 + slot,
                                             Submodules=subs))
        return ExpectedSubmoduleBlockReq(APIs=apis)

    def _rpc(self, ptype, pdu, seq, endian):
        to_device = ptype == 0
        rpc = DceRpc4(ptype=ptype, flags1=0x20 if to_device else 0x0A, endian=endian,
                      object=uuid.UUID("dea00000-6c97-11d1-8271-000100010130"),
                      if_id=uuid.UUID("dea00001-6c97-11d1-8271-00a02442df7d"),
                      act_id=uuid.UUID(int=(self.ar.int ^ seq)), seqnum=seq, opnum=0, ihint=0xFFFF, ahint=0xFFFF)
        src, dst = (self.ctl_mac, self.mac) if to_device else (self.mac, self.ctl_mac)
        sip, dip = (self.ctl_ip, self.ip) if to_device else (self.ip, self.ctl_ip)
        sport, dport = (0xC100, PNIO_CM) if to_device else (PNIO_CM, 0xC100)
        return Ether(src=src, dst=dst) / IP(src=sip, dst=dip, id=seq & 0xFFFF) / UDP(sport=sport, dport=dport) \
            / rpc / pdu

    def connect(self, seq=1, request_fids=None, endian=1):
        """The Connect request and its response. request_fids: the (input,
        output) FrameIDs the request carries (default: the real ones);
        0xFFFF leaves the FrameID to the device, whose response assigns
        in_fid / out_fid."""
        req_in, req_out = request_fids or (self.in_fid, self.out_fid)
        req = PNIOServiceReqPDU(args_max=16384, blocks=[
            ARBlockReq(ARType=1, ARUUID=self.ar, SessionKey=seq, CMInitiatorMacAdd=self.ctl_mac,
                       CMInitiatorObjectUUID=uuid.UUID("dea00000-6c97-11d1-8271-000100010130"),
                       ARProperties_ParametrizationServer=1, CMInitiatorActivityTimeoutFactor=600,
                       CMInitiatorStationName=b"plc"),
            self._iocr("in", 1, req_in),
            self._iocr("out", 2, req_out),
            AlarmCRBlockReq(),
            self._expected_submodules()])
        res = PNIOServiceResPDU(status=0, blocks=[
            ARBlockRes(ARType=1, ARUUID=self.ar, SessionKey=seq, CMResponderMacAdd=self.mac),
            IOCRBlockRes(IOCRType=1, IOCRReference=1, FrameID=self.in_fid),
            IOCRBlockRes(IOCRType=2, IOCRReference=2, FrameID=self.out_fid),
            AlarmCRBlockRes(LocalAlarmReference=3, MaxAlarmDataLength=200)])
        # Each block serialised once: scapy serialises nested block lists
        # again for every length field above them (10x slower, same bytes).
        req.blocks = [Raw(bytes(b)) for b in req.blocks]
        res.blocks = [Raw(bytes(b)) for b in res.blocks]
        return self._rpc(0, req, seq, endian), self._rpc(2, res, seq, endian)


class CaptureFile:
    """Packets with times, written as a classic pcap (Ethernet) readable by nobody."""

    def __init__(self):
        self.packets = []

    def add(self, pkt, dt=0.001):
        """Appends pkt `dt` seconds after the previous one; returns its frame number."""
        pkt.time = (self.packets[-1].time if self.packets else 1700000000) + dt
        self.packets.append(pkt)
        return len(self.packets)

    def write(self, path):
        with PcapWriter(str(path), linktype=1, sync=True) as w:
            for p in self.packets:
                w.write(p)
        path.chmod(0o644)
        return path


def iocs_first(direction, elements):
    """The IOCS first, then the IO data objects, each in slot order (the input
    CR of PC WORX RT Basic, public capture pnio_connect_many.pcapng)."""
    return [e for e in elements if e[0] == "iocs"] + [e for e in elements if e[0] == "data"]


def data_first(direction, elements):
    """The IO data objects first, then the IOCS, each in slot order."""
    return [e for e in elements if e[0] == "data"] + [e for e in elements if e[0] == "iocs"]


def mac(index):
    return "02:00:%02x:%02x:%02x:%02x" % ((index >> 24) & 0xFF, (index >> 16) & 0xFF, (index >> 8) & 0xFF,
                                          index & 0xFF)

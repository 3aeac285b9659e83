"""PROFINET IO scenarios: MC-MB2-PN (SP-14-023) and EC-Link (TS-0007) cyclic data.

A device is described by its submodules in slot order (the DAP submodules of
slot 0 first). `Device` builds the Connect request/response for it (DCE/RPC
over UDP 34964, as an IO controller sends it) and the cyclic C-SDUs: in each
direction every submodule with data in that direction puts its data and its
IOPS, and every submodule with data in the other direction puts its IOCS, in
slot order.
"""
import uuid

from scapy.contrib.pnio_rpc import (ARBlockReq, ARBlockRes, ExpectedSubmodule,
                                    ExpectedSubmoduleAPI, ExpectedSubmoduleBlockReq,
                                    ExpectedSubmoduleDataDescription, IOCRAPI, IOCRAPIObject,
                                    IOCRBlockReq, IOCRBlockRes, PNIOServiceReqPDU,
                                    PNIOServiceResPDU)
from scapy.layers.dcerpc import DceRpc4
from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import Dot1Q, Ether

from .frames import pn_rt_frame
from .pcap import Capture
from .registry import capture

CONTROLLER_MAC = "00:1b:1b:00:00:01"
DEVICE_MAC = "00:30:11:00:00:02"
CONTROLLER_IP = "192.168.0.1"
DEVICE_IP = "192.168.0.2"
PNIO_CM_PORT = 34964
GOOD = 0x80

# MC-MB2-PN module sizes (SP-14-023 section 5.3), largest first.
DATA_MODULES = (20, 10, 8, 4, 2)
ASCII_MODULES = (40, 20, 10, 8, 4, 2)


def split(size, modules=DATA_MODULES):
    """Module sizes for `size` bytes, largest first."""
    out = []
    for m in modules:
        while size >= m:
            out.append(m)
            size -= m
    assert size == 0, "size not made of modules"
    return out


class Sub:
    """One submodule: slot, subslot, input and output data length."""

    def __init__(self, slot, subslot, inlen=0, outlen=0, ident=1, module_ident=0x100):
        self.slot, self.subslot = slot, subslot
        self.inlen, self.outlen = inlen, outlen
        self.ident, self.module_ident = ident, module_ident

    @property
    def is_input(self):
        # A submodule without data (the DAP) is an input submodule.
        return self.inlen > 0 or self.outlen == 0

    @property
    def is_output(self):
        return self.outlen > 0


def dap_subs(count=4):
    subslots = [1, 0x8000, 0x8001, 0x8002][:count]
    return [Sub(0, s, 0, 0, ident=i + 1, module_ident=0x406) for i, s in enumerate(subslots)]


class Device:
    """An IO device with its submodules; lays out both cyclic frames."""

    def __init__(self, subs, in_fid, out_fid, device_mac=DEVICE_MAC, controller_mac=CONTROLLER_MAC,
                 vlan=None, ar_uuid="6d8b0a1c-2f3e-4a5b-8c9d-0e1f2a3b4c5d", order=None):
        self.subs = sorted(subs, key=lambda s: (s.slot, s.subslot))
        # The frame layout the controller assigns, per direction ("in",
        # "out"): "iocs_first" (the IOCS, then the IO data objects, each in
        # slot order: PC WORX RT Basic), "data_first", or slot order.
        self.order = order or {}
        self.in_fid, self.out_fid = in_fid, out_fid
        self.dev_mac, self.ctl_mac = device_mac, controller_mac
        self.vlan = vlan
        self.ar_uuid = ar_uuid
        self.in_off, self.in_iocs, self.in_len = self._layout("in")
        self.out_off, self.out_iocs, self.out_len = self._layout("out")
        self.cycle = 0

    def _layout(self, direction):
        """{sub: data offset}, {sub: IOCS offset}, C-SDU length of one direction."""
        elements = []
        for s in self.subs:
            if s.is_input if direction == "in" else s.is_output:
                elements.append(("data", s))
            if s.is_output if direction == "in" else s.is_input:
                elements.append(("iocs", s))
        first = {"iocs_first": "iocs", "data_first": "data"}.get(self.order.get(direction))
        if first:
            elements.sort(key=lambda e: e[0] != first)   # stable: slot order within each kind
        data, iocs, off = {}, {}, 0
        for kind, s in elements:
            if kind == "data":
                data[s] = off
                off += (s.inlen if direction == "in" else s.outlen) + 1
            else:
                iocs[s] = off
                off += 1
        return data, iocs, max(off, 40)

    # -- Connect -------------------------------------------------------------
    def _iocr(self, iocr_type, ref, fid, offs, iocs, length):
        objs = [IOCRAPIObject(SlotNumber=s.slot, SubslotNumber=s.subslot, FrameOffset=o)
                for s, o in offs.items()]
        cs = [IOCRAPIObject(SlotNumber=s.slot, SubslotNumber=s.subslot, FrameOffset=o)
              for s, o in iocs.items()]
        return IOCRBlockReq(IOCRType=iocr_type, IOCRReference=ref, IOCRProperties_RTClass=2,
                            DataLength=length, FrameID=fid, SendClockFactor=32, ReductionRatio=4,
                            IOCRMulticastMACAdd="00:00:00:00:00:00",
                            APIs=[IOCRAPI(API=0, IODataObjects=objs, IOCSs=cs)])

    def _expected(self):
        blocks = []
        for slot in sorted({s.slot for s in self.subs}):
            subs = [s for s in self.subs if s.slot == slot]
            esubs = []
            for s in subs:
                if s.inlen and s.outlen:
                    typ = 3
                    dd = [ExpectedSubmoduleDataDescription(DataDescription=1, SubmoduleDataLength=s.inlen,
                                                           LengthIOCS=1, LengthIOPS=1),
                          ExpectedSubmoduleDataDescription(DataDescription=2, SubmoduleDataLength=s.outlen,
                                                           LengthIOCS=1, LengthIOPS=1)]
                else:
                    typ = 2 if s.outlen else (1 if s.inlen else 0)
                    dd = [ExpectedSubmoduleDataDescription(DataDescription=2 if s.outlen else 1,
                                                           SubmoduleDataLength=s.outlen or s.inlen,
                                                           LengthIOCS=1, LengthIOPS=1)]
                esubs.append(ExpectedSubmodule(SubslotNumber=s.subslot, SubmoduleIdentNumber=s.ident,
                                               SubmoduleProperties_Type=typ, DataDescription=dd))
            blocks.append(ExpectedSubmoduleBlockReq(APIs=[ExpectedSubmoduleAPI(
                API=0, SlotNumber=slot, ModuleIdentNumber=subs[0].module_ident, Submodules=esubs)]))
        return blocks

    def _rpc(self, ptype, payload, src_is_ctl, seq, device_port=PNIO_CM_PORT):
        act = uuid.UUID("a0c1e2f3-0000-4000-8000-%012x" % seq)
        obj = uuid.UUID("dea00000-6c97-11d1-8271-000100010130")
        if_id = uuid.UUID("dea00001-6c97-11d1-8271-00a02442df7d")
        rpc = DceRpc4(ptype=ptype, flags1=0x20 if ptype == 0 else 0x0A, endian=1, object=obj,
                      if_id=if_id, act_id=act, seqnum=seq, opnum=0, ihint=0xFFFF, ahint=0xFFFF)
        body = bytes(rpc / payload)
        src_mac, dst_mac = (self.ctl_mac, self.dev_mac) if src_is_ctl else (self.dev_mac, self.ctl_mac)
        src_ip, dst_ip = (CONTROLLER_IP, DEVICE_IP) if src_is_ctl else (DEVICE_IP, CONTROLLER_IP)
        sport, dport = (0xC001, PNIO_CM_PORT) if src_is_ctl else (device_port, 0xC001)
        eth = Ether(src=src_mac, dst=dst_mac)
        if self.vlan is not None:
            eth = eth / Dot1Q(prio=0, vlan=self.vlan)
        return bytes(eth / IP(src=src_ip, dst=dst_ip, ttl=64, id=0x100 + seq)
                     / UDP(sport=sport, dport=dport) / body)

    def connect(self, cap, t, seq=1, response_in_fid=None, device_port=PNIO_CM_PORT):
        """Add the Connect request and its response (sent from device_port); returns their frame numbers."""
        ar = uuid.UUID(self.ar_uuid)
        blocks = [ARBlockReq(ARType=1, ARUUID=ar, SessionKey=1, CMInitiatorMacAdd=self.ctl_mac,
                             CMInitiatorObjectUUID=uuid.UUID("dea00000-6c97-11d1-8271-000100010130"),
                             ARProperties_ParametrizationServer=1, CMInitiatorActivityTimeoutFactor=600,
                             CMInitiatorStationName=b"plc1"),
                  self._iocr(1, 1, 0xFFFF if response_in_fid else self.in_fid, self.in_off, self.in_iocs,
                             self.in_len),
                  self._iocr(2, 2, self.out_fid, self.out_off, self.out_iocs, self.out_len)]
        blocks += self._expected()
        req = PNIOServiceReqPDU(args_max=4096, blocks=blocks)
        res_blocks = [ARBlockRes(ARType=1, ARUUID=ar, SessionKey=1, CMResponderMacAdd=self.dev_mac),
                      IOCRBlockRes(IOCRType=1, IOCRReference=1, FrameID=response_in_fid or self.in_fid),
                      IOCRBlockRes(IOCRType=2, IOCRReference=2, FrameID=self.out_fid)]
        res = PNIOServiceResPDU(status=0, blocks=res_blocks)
        a = cap.add(t, self._rpc(0, req, True, seq))
        b = cap.add(t + 0.01, self._rpc(2, res, False, seq, device_port))
        return a, b

    # -- cyclic data -----------------------------------------------------------
    def _csdu(self, direction, data, iops, iocs):
        offs = self.in_off if direction == "in" else self.out_off
        cs = self.in_iocs if direction == "in" else self.out_iocs
        buf = bytearray(self.in_len if direction == "in" else self.out_len)
        for s, o in offs.items():
            n = s.inlen if direction == "in" else s.outlen
            b = bytes(data.get((s.slot, s.subslot), bytes(n)))
            assert len(b) == n, (s.slot, s.subslot, len(b), n)
            buf[o:o + n] = b
            buf[o + n] = iops.get((s.slot, s.subslot), GOOD)
        for s, o in cs.items():
            buf[o] = iocs.get((s.slot, s.subslot), GOOD)
        return bytes(buf)

    def frame(self, cap, t, direction, data, iops=None, iocs=None, fid=None, cycle=None):
        """Add one cyclic frame; data: {(slot, subslot): bytes}; cycle: its
        cycle counter (default: one counter for both directions, +32 a frame)."""
        self.cycle = (self.cycle + 32) & 0xFFFF if cycle is None else cycle & 0xFFFF
        c_sdu = self._csdu(direction, data, iops or {}, iocs or {})
        if direction == "in":
            src, dst, f = self.dev_mac, self.ctl_mac, self.in_fid
        else:
            src, dst, f = self.ctl_mac, self.dev_mac, self.out_fid
        return cap.add(t, pn_rt_frame(src, dst, fid or f, c_sdu, cycle=self.cycle, vlan=self.vlan))


class Mcmb2(Device):
    """An MC-MB2-PN with its modules in the order of SP-14-023 section 5.3.

    up: uplink data bytes per terminal, down: (data, ASCII) downlink bytes per
    terminal; terminals: 1 for duplex/simplex, the configured slots for polled.
    """

    def __init__(self, system, up, down, terminals=1, ascii_=0, dap=4, **kw):
        self.system = system
        self.up_bytes, self.down_bytes, self.ascii_bytes = up, down, ascii_
        subs = dap_subs(dap)
        slot = 1
        self.up_header = Sub(slot, 1, inlen=2 if system == "duplex" else 8, module_ident=0x10)
        subs.append(self.up_header)
        self.up_groups = []
        for _ in range(terminals):
            group = []
            for m in split(up):
                slot += 1
                group.append(Sub(slot, 1, inlen=m, module_ident=0x20 + m))
            self.up_groups.append(group)
            subs += group
        slot += 1
        self.down_header = Sub(slot, 1, outlen=2, module_ident=0x30)
        subs.append(self.down_header)
        self.down_groups = []
        for _ in range(terminals):
            group = []
            for m in split(down):
                slot += 1
                group.append(Sub(slot, 1, outlen=m, module_ident=0x40 + m))
            for m in split(ascii_, ASCII_MODULES):
                slot += 1
                group.append(Sub(slot, 1, outlen=m, module_ident=0x80 + m))
            self.down_groups.append(group)
            subs += group
        super().__init__(subs, **kw)

    @staticmethod
    def _spread(groups, payloads):
        data = {}
        for group, payload in zip(groups, payloads):
            payload = bytes(payload)
            o = 0
            for s in group:
                n = s.inlen or s.outlen
                data[(s.slot, s.subslot)] = payload[o:o + n]
                o += n
            assert o == len(payload), "payload does not fill the terminal's modules"
        return data

    def uplink(self, cap, t, header, payloads, iops=None, **kw):
        """header: the 2 (duplex) or 8 (polled) header bytes; payloads: one per terminal."""
        data = self._spread(self.up_groups, payloads)
        data[(self.up_header.slot, 1)] = bytes(header)
        return self.frame(cap, t, "in", data, iops=iops, **kw)

    def downlink(self, cap, t, header, payloads, iops=None, **kw):
        data = self._spread(self.down_groups, payloads)
        data[(self.down_header.slot, 1)] = bytes(header)
        return self.frame(cap, t, "out", data, iops=iops, **kw)


def _duplex_payload(n, seed):
    return bytes(((seed * 7 + i) & 0xFF) or 1 for i in range(n))


@capture("mcmb2_duplex_connect.pcap",
         "MC-MB2-PN duplex with its Connect: 26 uplink bytes (20+4+2), 10+20 ASCII downlink; "
         "every status, each undefined status, data with status not 1, bad IOPS/IOCS")
def duplex_connect():
    cap = Capture()
    d = Mcmb2("duplex", 26, 10, ascii_=20, in_fid=0x8001, out_fid=0x8002)
    d.connect(cap, 0.0)                                          # frames 1, 2
    zero = bytes(26)
    # (status byte, uplink data, uplink IOPS, downlink IOCS)
    steps = [(0x00, zero, None, None),          # 3/4   absent, scanning
             (0x12, zero, None, None),          # 5/6   blocked, terminal 1
             (0x11, _duplex_payload(26, 1), None, None),   # 7/8 present
             (0x11, _duplex_payload(26, 2), {(3, 1): 0x00}, None),  # 9/10 bad IOPS slot 3
             (0x17, _duplex_payload(26, 3), None, None),   # 11/12 active stop, data not 0
             (0x1A, zero, None, None),          # 13/14 fieldbus failure
             (0x11, _duplex_payload(26, 4), None, {(1, 1): 0x60})]  # 15/16 bad IOCS in downlink
    for st in (3, 4, 5, 6, 8, 9, 0xB, 0xC, 0xD, 0xE, 0xF):     # 17.. undefined statuses
        steps.append((0x10 | st, zero, None, None))
    t = 0.1
    for i, (status, data, iops, iocs) in enumerate(steps):
        d.uplink(cap, t, [status, i + 1], [data], iops=iops)
        d.downlink(cap, t + 0.001, [1, i + 1], [_duplex_payload(30, 100 + i)], iocs=iocs)
        t += 0.1
    return cap


@capture("mcmb2_duplex_cm_port.pcap",
         "MC-MB2-PN duplex whose Connect response comes from the device's own UDP port and assigns the "
         "input FrameID (0x8101); an unrelated datagram to the controller's port")
def duplex_cm_port():
    cap = Capture()
    d = Mcmb2("duplex", 8, 4, in_fid=0x8101, out_fid=0x8102)
    d.connect(cap, 0.0, response_in_fid=0x8101, device_port=0xC005)     # frames 1, 2
    for i in range(3):                                                   # frames 3..8
        d.uplink(cap, 0.1 + i * 0.1, [0x11, i + 1], [_duplex_payload(8, i)])
        d.downlink(cap, 0.101 + i * 0.1, [1, i + 1], [_duplex_payload(4, 50 + i)])
    # frame 9: not DCE/RPC, to the controller's port: left to Wireshark
    cap.add(0.5, bytes(Ether(src=DEVICE_MAC, dst=CONTROLLER_MAC) / IP(src=DEVICE_IP, dst=CONTROLLER_IP)
                       / UDP(sport=0xC006, dport=0xC001) / b"hello"))
    return cap


@capture("mcmb2_duplex_watchdog.pcap",
         "MC-MB2-PN simplex with its Connect: uplink watchdog stalls 1.2 s, downlink watchdog stalls 2.2 s")
def duplex_watchdog(connect=True):
    cap = Capture()
    d = Mcmb2("duplex", 4, 0, in_fid=0x8003, out_fid=0x8004)
    if connect:
        d.connect(cap, 0.0)
    up_wd = down_wd = 0
    for i in range(25):
        t = 0.2 + i * 0.2
        # uplink frozen from tick 4 to 11 (t 1.0 .. 2.4), downlink from 4 to 16 (t 1.0 .. 3.4)
        if not 4 < i <= 11:
            up_wd += 1
        if not 4 < i <= 16:
            down_wd += 1
        d.uplink(cap, t, [0x11, up_wd & 0xFF], [bytes([1, 2, 3, i])])
        d.downlink(cap, t + 0.001, [0, down_wd & 0xFF], [])
    return cap


@capture("mcmb2_duplex_stops.pcap",
         "MC-MB2-PN duplex with its Connect (cycle 4 ms, data hold 40 ms): 3 uplink frames lost, the uplink "
         "ends at 0.216 s while the downlink runs on to 1.297 s, then another device's frames to 3.45 s")
def duplex_stops():
    base = Mcmb2("duplex", 4, 2, in_fid=0x8005, out_fid=0x8006)
    other = ("00:30:11:00:00:99", "00:1b:1b:00:00:98", 0x0400)
    cap = Capture()
    base.connect(cap, 0.0)                                               # frames 1, 2
    # a 4 ms tick i: the uplink (ticks 0-29 but 10-12), then the downlink
    # (ticks 0-299) 1 ms later, each stream its own cycle counter stepping
    # by the Connect's 32 x 4; then the other device every 0.1 s
    uplinks = set(range(30)) - {10, 11, 12}
    for tick in range(300):
        at = 0.1 + tick * 0.004
        if tick in uplinks:
            base.uplink(cap, at, [0x11, tick // 6], [bytes([1, 2, 3, tick])], cycle=tick * 128)
        base.downlink(cap, at + 0.001, [0, tick // 25], [bytes([0, tick & 0xFF])], cycle=tick * 128)
    for k in range(22):
        cap.add(1.35 + k * 0.1, pn_rt_frame(*other, bytes(40), cycle=k * 3200))
    return cap


@capture("mcmb2_simplex_unwritten.pcap",
         "MC-MB2-PN simplex with its Connect whose controller never writes the downlink watchdog, the base "
         "reporting Terminal present (not configured to monitor it, SP-14-023 3.2.2): a note, not E010")
def simplex_unwritten():
    cap = Capture()
    d = Mcmb2("duplex", 8, 0, in_fid=0x8005, out_fid=0x8006)
    d.connect(cap, 0.0)                                          # frames 1, 2
    for i in range(16):                                          # 3/4, 5/6 ...
        t = 0.1 + i * 0.15
        d.uplink(cap, t, [0x11, (i + 1) & 0xFF], [_duplex_payload(8, i)])
        d.downlink(cap, t + 0.001, [0, 0], [])                   # past 2 s at i = 14: frame 32
    return cap


@capture("mcmb2_duplex_watchdog_steps.pcap",
         "MC-MB2-PN simplex with its Connect: watchdogs that are not incremented by one (SP-14-023 2.4): "
         "uplink jumps 4 -> 7 and goes back 9 -> 3, downlink wraps 255 -> 0, goes back 1 -> 0 and jumps 1 -> 5")
def duplex_watchdog_steps():
    cap = Capture()
    d = Mcmb2("duplex", 4, 0, in_fid=0x8005, out_fid=0x8006)
    d.connect(cap, 0.0)                                     # frames 1, 2
    up = [1, 2, 3, 4, 7, 8, 9, 3]                           # jump at 11, back at 17
    down = [254, 255, 0, 1, 0, 1, 5, 6]                     # back at 12, jump at 16
    for i, (u, w) in enumerate(zip(up, down)):              # uplink 3 + 2i, downlink 4 + 2i
        t = 0.1 + i * 0.1
        d.uplink(cap, t, [0x11, u], [bytes([1, 2, 3, i])])
        d.downlink(cap, t + 0.001, [0, w], [])
    return cap


@capture("mcmb2_duplex_midsession.pcap",
         "The same simplex base without its Connect (captured mid-session): layout inferred from the cyclic frames")
def duplex_midsession():
    return duplex_watchdog(connect=False)


def _polled_header(status, wd, y, z, slots):
    return [status, wd, y, z] + list(slots)


@capture("mcmb2_polled_connect.pcap",
         "MC-MB2-PN polled with its Connect: 3 slots (Y=24: 20+4, Z=10), slot 4 unused; dynamic polling, "
         "undefined slot and system status, Y/Z mismatch, reserved byte")
def polled_connect():
    cap = Capture()
    d = Mcmb2("polled", 24, 10, terminals=3, in_fid=0x8005, out_fid=0x8006)
    d.connect(cap, 0.0)                                           # 1, 2
    pay = [bytes([0x10 + k] * 24) for k in range(3)]
    zero = bytes(24)
    down = [bytes([0xA0 + k] * 10) for k in range(3)]
    steps = [
        (0x0F, 24, 10, (0x11, 0x21, 0x31, 0x0F), pay, 0),               # 3/4 normal
        (0x0F, 24, 10, (0x11, 0x20, 0x31, 0x0F), [pay[0], zero, pay[2]], 0),  # 5/6 slot 2 absent
        (0x0F, 24, 10, (0x11, 0x51, 0x31, 0x0F), pay, 0),               # 7/8 slot 2: terminal 5
        (0x0F, 24, 10, (0x11, 0x51, 0x33, 0x0F), [pay[0], pay[1], zero], 0),  # 9/10 slot 3 undefined 3
        (0x01, 24, 10, (0x11, 0x51, 0x31, 0x0F), pay, 0),               # 11/12 status 1 undefined (polled)
        (0x0A, 24, 10, (0x10, 0x50, 0x30, 0x0F), [zero, zero, zero], 0),  # 13/14 fieldbus failure
        (0x0F, 20, 10, (0x11, 0x51, 0x31, 0x0F), pay, 0),               # 15/16 Y mismatch
        (0x2F, 24, 10, (0x11, 0x57, 0x31, 0x0F), [pay[0], pay[1], pay[2]], 5),  # 17/18 terminal bits, stop w/ data, reserved
    ]
    t = 0.1
    for i, (st, y, z, slots, payloads, reserved) in enumerate(steps):
        d.uplink(cap, t, _polled_header(st, i + 1, y, z, slots), payloads)
        d.downlink(cap, t + 0.001, [reserved, i + 1], down)
        t += 0.1
    return cap


def _polled_noconnect(vlan):
    cap = Capture()
    d = Mcmb2("polled", 10, 4, terminals=2, in_fid=0xC001, out_fid=0xC002, vlan=vlan)
    pay = [bytes([0x30 + k] * 10) for k in range(2)]
    down = [bytes([0x40 + k] * 4) for k in range(2)]
    t = 0.1
    # The controller starts first: its downlink before any uplink is not decoded.
    d.downlink(cap, t, [0, 1], down)                                  # 1
    for i in range(6):
        t += 0.1
        slots = (0x11, 0x21 if i < 3 else 0x41, 0x0F, 0x0F)            # slot 2 changes terminal at 5th uplink
        d.uplink(cap, t, _polled_header(0x0F, i + 1, 10, 4, slots), pay)
        d.downlink(cap, t + 0.001, [0, i + 2], down)
    return cap


@capture("mcmb2_polled_noconnect.pcap",
         "MC-MB2-PN polled without a Connect (FrameIDs 0xC001/0xC002): laid out from the polled header")
def polled_noconnect():
    return _polled_noconnect(None)


@capture("mcmb2_polled_vlan.pcap", "The same as mcmb2_polled_noconnect.pcap, 802.1Q tagged (VLAN 100)")
def polled_vlan():
    return _polled_noconnect(100)


def _duplex_pairs(d, pairs, up, down):
    """pairs uplink + downlink frames 0.1 s apart; up(i), down(i): (header, payload)."""
    cap = Capture()
    for i in range(pairs):
        t = 0.1 * (i + 1)
        header, payload = up(i)
        d.uplink(cap, t, header, [payload])
        header, payload = down(i)
        d.downlink(cap, t + 0.001, header, [payload])
    return cap


@capture("mcmb2_duplex_noconnect.pcap",
         "MC-MB2-PN duplex without a Connect (FrameIDs 0xC010/0xC011, 8 up / 4 down bytes): layout "
         "inferred from its cyclic frames, or from the mcmb2.layouts preference")
def duplex_noconnect():
    return _duplex_pairs(Mcmb2("duplex", 8, 4, in_fid=0xC010, out_fid=0xC011), 3,
                         lambda i: ([0x31, i + 1], bytes(range(1, 9))), lambda i: ([2, i + 1], bytes([9, 8, 7, 6])))


@capture("mcmb2_duplex_pcworx.pcap",
         "MC-MB2-PN duplex without a Connect (FrameIDs 0xC012/0xC013, 26 up / 2 + 8 ASCII down bytes), laid "
         "out as PC WORX RT Basic does: the IOCS first, then the IO data objects; layout inferred from its "
         "cyclic frames")
def duplex_pcworx():
    d = Mcmb2("duplex", 26, 2, ascii_=8, in_fid=0xC012, out_fid=0xC013,
              order={"in": "iocs_first", "out": "iocs_first"})
    return _duplex_pairs(d, 3, lambda i: ([0x31, i + 1], _duplex_payload(26, i)),
                         lambda i: ([0, i + 1], bytes([9, 8]) + b"HOIST UP"))


@capture("mcmb2_duplex_e010_noconnect.pcap",
         "MC-MB2-PN duplex without a Connect (FrameIDs 0xC014/0xC015, 8 up / 4 down bytes) in E010: its "
         "downlink watchdog never moves, so its layout is never inferred; every frame carries the note "
         "mcmb2.candidate with the setting that decodes it (second pass)")
def duplex_e010_noconnect():
    return _duplex_pairs(Mcmb2("duplex", 8, 4, in_fid=0xC014, out_fid=0xC015), 5,
                         lambda i: ([0x3A, i + 1], bytes(8)), lambda i: ([0, 7], bytes([9, 8, 7, 6])))


@capture("mcmb2_duplex_reopen_noconnect.pcap",
         "MC-MB2-PN duplex without a Connect (FrameIDs 0xC016/0xC017, 8 up / 4 down bytes): its layout, "
         "inferred in frame 6, is contradicted in frame 9 (the DAP's IOPS is 0x81, neither GOOD nor BAD): the "
         "inference is re-opened there (mcmb2.layout.reopened) and settles again in frame 15")
def duplex_reopen_noconnect():
    d = Mcmb2("duplex", 8, 4, in_fid=0xC016, out_fid=0xC017)
    cap = Capture()
    for i in range(8):
        t = 0.1 * (i + 1)
        d.uplink(cap, t, [0x31, i + 1], [bytes(range(1, 9))], iops={(0, 1): 0x81} if i == 4 else None)
        d.downlink(cap, t + 0.001, [0, i + 1], [bytes([9, 8, 7, 6])])
    return cap


# -- EC-Link -------------------------------------------------------------------
def eclink_input(pci, cci, cai, bu=0x11, pai=0):
    img = bytearray(64)
    img[0:4] = bytes([pci & 0xFF, cci & 0xFF, pai, cai & 0xFF])
    img[4:20] = bytes(range(0x41, 0x51))
    img[20:26] = bytes([bu, 1, 0, 1, 1, 1])
    img[26:28] = (0x1234).to_bytes(2, "big")
    img[28:34] = bytes([3, 80, 90, 0, 0, 0])
    img[34:36] = (500).to_bytes(2, "big", signed=True)
    img[36:38] = (-250).to_bytes(2, "big", signed=True)
    img[42:44] = (1).to_bytes(2, "big")
    img[58:60] = bytes([7, 0])
    return bytes(img)


def eclink_output(pco, cco, cao, length=224):
    img = bytearray(length)
    img[0:4] = bytes([pco & 0xFF, cco & 0xFF, 0, cao & 0xFF])
    img[4:20] = bytes(range(0x61, 0x71))
    if length == 224:
        img[20:22] = (10).to_bytes(2, "big")
        img[24:34] = bytes(range(1, 11))
    return bytes(img)


class EclinkBu(Device):
    def __init__(self, outlen, **kw):
        subs = dap_subs(4) + [Sub(1, 1, inlen=64, module_ident=0x101)]
        if outlen:
            subs.append(Sub(2, 1, outlen=outlen, module_ident=0x102 if outlen == 20 else 0x103))
        self.outlen = outlen
        super().__init__(subs, **kw)

    def inputs(self, cap, t, img, **kw):
        return self.frame(cap, t, "in", {(1, 1): img}, **kw)

    def outputs(self, cap, t, img, **kw):
        return self.frame(cap, t, "out", {(2, 1): img}, **kw)


@capture("eclink_pnio_connect.pcap",
         "EC-Link BU (Standard, 64 in / 224 out) with its Connect: CCI->CAO and CCO->CAI handshakes, a CCI "
         "not acknowledged, PCI stall, PCO stall, BU state change")
def eclink_connect():
    cap = Capture()
    bu = EclinkBu(224, in_fid=0x8010, out_fid=0x8011)
    bu.connect(cap, 0.0)                                              # 1, 2
    pci = cci = cai = pco = cco = cao = 0
    for i in range(40):
        t = 0.125 * (i + 1)
        if not 10 <= i < 16:          # PCI frozen for 6 ticks (0.75 s)
            pci += 1
        if i == 3:
            cci += 1                  # command from RU, acknowledged two ticks later
        if i == 5:
            cao = cci
        if i == 8:
            cco += 1                  # command to RU, CAI follows one tick later
        if i == 9:
            cai = cco
        if i == 20:
            cci += 1                  # never acknowledged
        if not 18 <= i < 38:          # PCO frozen for 20 ticks (2.5 s)
            pco += 1
        bu_state = 0x10 if i < 2 else 0x11
        bu.inputs(cap, t, eclink_input(pci, cci, cai, bu=bu_state))
        bu.outputs(cap, t + 0.001, eclink_output(pco, cco, cao))
    return cap


@capture("eclink_pnio_data_first.pcap",
         "EC-Link BU (Standard, 64 in / 224 out) without a Connect (FrameIDs 0xC022/0xC023): the IOCS first "
         "in the uplink, the output image first and the IOCS last in the downlink; layout inferred from its "
         "cyclic frames")
def eclink_data_first():
    cap = Capture()
    bu = EclinkBu(224, in_fid=0xC022, out_fid=0xC023, order={"in": "iocs_first", "out": "data_first"})
    for i in range(4):
        t = 0.125 * (i + 1)
        bu.inputs(cap, t, eclink_input(i + 1, 0, 0))
        bu.outputs(cap, t + 0.001, eclink_output(i + 1, 0, 0))
    return cap


@capture("eclink_pnio_noconnect.pcap",
         "EC-Link BU (Input + Commands, 64 in / 20 out) without a Connect (FrameIDs 0xC020/0xC021): layout "
         "inferred from its cyclic frames, or from the mcmb2.layouts preference")
def eclink_noconnect():
    cap = Capture()
    bu = EclinkBu(20, in_fid=0xC020, out_fid=0xC021)
    for i in range(4):
        t = 0.125 * (i + 1)
        bu.inputs(cap, t, eclink_input(i + 1, 0, 0))
        bu.outputs(cap, t + 0.001, eclink_output(i + 1, 0, 0, length=20))
    return cap


def _eclink_mode(outlen, connect, in_fid, out_fid):
    """A BU in Input + Commands (outlen 20) or Input Only (0) mode, TS-0007
    2.1 / 4.3: 24 cycles 125 ms apart (3 s). The controller never touches
    PCO (the mode's guide, 4.1, skips "update PCO"); the RU sends a command
    (CCI 1 -> 2) at cycle 6, which the controller echoes in CAO at cycle 7
    (Input + Commands only; Input Only transfers no commands)."""
    cap = Capture()
    bu = EclinkBu(outlen, in_fid=in_fid, out_fid=out_fid)
    if connect:
        bu.connect(cap, 0.0)                                     # 1, 2
    cci = cao = 1
    for i in range(24):
        t = 0.1 + i * 0.125
        if i == 6 and outlen:
            cci = 2
        if i == 7:
            cao = cci
        bu.inputs(cap, t, eclink_input(i + 1, cci, 0))
        if outlen:
            bu.outputs(cap, t + 0.001, eclink_output(0, 0, cao, length=outlen))
        else:
            bu.frame(cap, t + 0.001, "out", {})                  # IOCS only
    return cap


@capture("eclink_pnio_commands.pcap",
         "EC-Link BU in Input + Commands mode (64 in / 20 out) with its Connect: PCO never moves (3 s), a "
         "command from RU echoed by CAO; the mode noted, no PCO stall (TS-0007 2.1, 8.4)")
def eclink_commands():
    return _eclink_mode(20, True, 0x8030, 0x8031)


@capture("eclink_pnio_commands_noconnect.pcap",
         "The same Input + Commands BU without its Connect (FrameIDs 0xC030/0xC031): layout inferred from the "
         "input image's PCI chain, the output image standing")
def eclink_commands_noconnect():
    return _eclink_mode(20, False, 0xC030, 0xC031)


@capture("eclink_pnio_input_only.pcap",
         "EC-Link BU in Input Only mode (64 in, no output image: an output CR with IOCS only) with its Connect")
def eclink_input_only():
    return _eclink_mode(0, True, 0x8032, 0x8033)


@capture("eclink_pnio_input_only_noconnect.pcap",
         "The same Input Only BU without its Connect (FrameIDs 0xC032/0xC033): layout inferred")
def eclink_input_only_noconnect():
    return _eclink_mode(0, False, 0xC032, 0xC033)

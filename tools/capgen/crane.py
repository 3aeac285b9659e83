"""The demo crane of examples/crane/: its machine data (IO list crane.csv)
carried over EG-Link (captures/crane_eglink.pcap), MC-MB2-PN
(captures/crane_mcmb2.pcap) and EC-Link in PROFINET and Modbus/TCP
(captures/crane_eclink_pnio.pcap, captures/crane_eclink_modbus.pcap).

The RU sends the operator's commands (buttons, speed range, hoist and trolley
joysticks) as VRCI command data; the crane controller answers with VRCO
messages (a code and a text) and sends its state (load, hook height, slew
angle, alarms, cycle counter, wind speed, status text) as VRPO periodic data.
The layouts are those of examples/crane/crane.csv.

The demo crane has device identities of its own, which no other capture
uses: the IO list's rows are limited to them (its `device` column), so that
the demo list, left installed, never names another machine's data.
"""
import struct

from . import eclink_modbus, eglink, profinet
from .pcap import Capture
from .registry import capture


def operator(horn=0, start=0, stop=0, gear=0, hoist=0, trolley=0, operator_id=7):
    """cmd.from_ru: buttons (byte 0 bits 0-2), speed range (bits 4-5), joysticks in 0.1 %."""
    buttons = horn | start << 1 | stop << 2 | gear << 4
    return struct.pack("<BxhhB", buttons, hoist, trolley, operator_id)


def message(code, text):
    """cmd.to_ru: message code (byte 0), text (bytes 2-13)."""
    return struct.pack("<Bx", code) + text.encode("ascii").ljust(12)[:12]


def state(load, height, slew, overload=0, wind_alarm=0, mode=0, cycle=0, wind=0.0, text=""):
    """periodic.to_ru: load 0.01 t, height 0.1 m - 20 m, slew 0.1 deg, alarms, cycle, wind, text."""
    flags = overload | wind_alarm << 1 | mode << 4
    return (struct.pack("<HhHBxIf", load, height, slew, flags, cycle, wind)
            + text.encode("ascii").ljust(16)[:16])


# The demo crane's identities (examples/crane/crane.csv, column device).
EGLINK_ORIGIN = 0x2C01              # the BU's origin
MCMB2_FIDS = (0x8021, 0x8022)       # MC-MB2-PN uplink, downlink FrameID
ECLINK_PNIO_FIDS = (0x8023, 0x8024)  # EC-Link in PROFINET: input, output image FrameID
ECLINK_MODBUS_SERVER = "192.168.2.71"  # EC-Link in Modbus/TCP: the BU (server)


# (t, who, type, payload): the session of the demo, in time order: VRPO every 200 ms
# (TS-0006 5.1.2), each sender's commands numbered 1, 2, ... (TS-0006 4.3, 4.5).
def _session():
    return [
        (0.000, "ctrl", "VRPO", state(0, 450, 900, mode=0, cycle=1, wind=3.5, text="READY")),
        (0.100, "bu", "VRCI", eglink.command(1, operator(start=1))),
        (0.110, "ctrl", "VRAO", eglink.ack(1)),
        (0.200, "ctrl", "VRPO", state(1250, 450, 900, mode=3, cycle=2, wind=4.25, text="RUNNING")),
        (0.300, "bu", "VRCI", eglink.command(2, operator(gear=1, hoist=755, trolley=-250))),
        (0.310, "ctrl", "VRAO", eglink.ack(2)),
        (0.400, "ctrl", "VRPO", state(1250, 512, 901, mode=1, cycle=3, wind=4.5, text="LIFTING")),
        (0.500, "bu", "VRCI", eglink.command(3, operator(horn=1, gear=2, hoist=1000, trolley=-1000))),
        (0.510, "ctrl", "VRAO", eglink.ack(3)),
        (0.600, "ctrl", "VRPO", state(5230, 640, 3599, overload=1, mode=3, cycle=4, wind=12.75,
                                      text="OVERLOAD")),
        (0.700, "ctrl", "VRCO", eglink.command(1, message(1, "LOAD 52.3 T"))),
        (0.710, "bu", "VRAI", eglink.ack(1)),
        (0.750, "bu", "VRCI", eglink.command(4, operator(stop=1, gear=3, hoist=-500))),
        (0.760, "ctrl", "VRAO", eglink.ack(4)),
        (0.800, "ctrl", "VRPO", state(5230, 200, 0, wind_alarm=1, mode=2, cycle=5, wind=21.0,
                                      text="WIND ALARM")),
        (1.000, "ctrl", "VRCO", eglink.command(2, message(2, "WIND 21 M/S"))),
        (1.010, "bu", "VRAI", eglink.ack(2)),
    ]


@capture("crane_eglink.pcap", "the demo crane (examples/crane/crane.csv) over EG-Link: "
         "operator commands (VRCI), controller messages (VRCO) and crane state (VRPO)")
def crane_eglink():
    link = eglink.Link(origin=EGLINK_ORIGIN)
    for t, who, ptype, payload in _session():
        if who == "bu":
            link.bu(t, ptype, payload)
        else:
            link.ctrl(t, ptype, eglink.vrpo(0, payload) if ptype == "VRPO" else payload)
    return link.cap


@capture("crane_mcmb2.pcap", "the demo crane (examples/crane/crane.csv) over MC-MB2-PN duplex with its "
         "Connect: the operator's terminal 1 uplink (8 bytes), messages downlink (14 bytes)")
def crane_mcmb2():
    cap = Capture()
    d = profinet.Mcmb2("duplex", 8, 14, in_fid=MCMB2_FIDS[0], out_fid=MCMB2_FIDS[1])
    d.connect(cap, 0.0)                                                       # frames 1, 2
    steps = [  # (uplink data, downlink data): frames 3/4, 5/6, 7/8, 9/10
        (operator(start=1), message(0, "")),
        (operator(gear=1, hoist=755, trolley=-250), message(0, "")),
        (operator(horn=1, gear=2, hoist=1000, trolley=-1000), message(1, "LOAD 52.3 T")),
        (operator(stop=1, gear=3, hoist=-500), message(2, "WIND 21 M/S")),
    ]
    for i, (up, down) in enumerate(steps):
        t = 0.1 * (i + 1)
        d.uplink(cap, t, [0x11, i + 1], [up + bytes(8 - len(up))])
        d.downlink(cap, t + 0.001, [1, i + 1], [down])
    return cap


# (command from the RU, command to the RU, crane state) of the EC-Link captures
def _eclink_steps():
    return [
        (operator(start=1), message(0, ""), state(0, 450, 900, cycle=1, wind=3.5, text="READY")),
        (operator(gear=1, hoist=755, trolley=-250), message(0, ""),
         state(1250, 512, 901, mode=1, cycle=3, wind=4.5, text="LIFTING")),
        (operator(horn=1, gear=2, hoist=1000, trolley=-1000), message(1, "LOAD 52.3 T"),
         state(5230, 640, 3599, overload=1, mode=3, cycle=4, wind=12.75, text="OVERLOAD")),
        (operator(stop=1, gear=3, hoist=-500), message(2, "WIND 21 M/S"),
         state(5230, 200, 0, wind_alarm=1, mode=2, cycle=5, wind=21.0, text="WIND ALARM")),
    ]


def _eclink_images(i, cmd_in, cmd_out, periodic):
    """The input and output image of cycle i (the periodic data fits in block 0)."""
    inp = eclink_modbus.input_image(pci=i + 1, cci=i + 1, pai=i, cmd=cmd_in)
    out = eclink_modbus.output_image(pco=i + 1, cco=i, cao=i + 1, cmd=cmd_out, size=len(periodic),
                                     block=0, data=periodic)
    return inp, out


@capture("crane_eclink_pnio.pcap", "the demo crane (examples/crane/crane.csv) over EC-Link in PROFINET "
         "(64 in / 224 out) with its Connect: operator commands in the input image, messages and the "
         "crane state (periodic data) in the output image")
def crane_eclink_pnio():
    cap = Capture()
    bu = profinet.EclinkBu(224, in_fid=ECLINK_PNIO_FIDS[0], out_fid=ECLINK_PNIO_FIDS[1])
    bu.connect(cap, 0.0)                                                     # frames 1, 2
    for i, step in enumerate(_eclink_steps()):                               # frames 3/4 .. 9/10
        inp, out = _eclink_images(i, *step)
        bu.inputs(cap, 0.125 * (i + 1), inp)
        bu.outputs(cap, 0.125 * (i + 1) + 0.001, out)
    return cap


@capture("crane_eclink_modbus.pcap", "the demo crane (examples/crane/crane.csv) over EC-Link in Modbus/TCP: "
         "operator commands in the input image, messages and the crane state (periodic data) in the output image")
def crane_eclink_modbus():
    cap = Capture()
    mb = eclink_modbus.ModbusClient(cap, server_ip=ECLINK_MODBUS_SERVER)   # frames 1-3: TCP handshake
    for i, step in enumerate(_eclink_steps()):             # frames 4-7, 8-11, 12-15, 16-19
        eclink_modbus.cycle(mb, 0.1 + 0.125 * i, *_eclink_images(i, *step))
    return cap

"""A BU's evidence is one definition: the Modbus addresses of its images in
the seam contract (VRSHARK_MB_INPUT_*, VRSHARK_MB_OUTPUT_* of
plugins/vrshark/vrshark-frontends.h; seam.luam's MB_INPUT_*, MB_OUTPUT_*,
held equal by tests/test_seam.py), read by the C front end
(vrshark-frontends.c:mb_evidence_request) and by the Lua decoder
(eclink_modbus.lua: REGIONS, full_input, full_output_write).

The same requests, every function code a controller polls with (1-4, 15,
16, 23) at and around each bound, go to a TCP port nobody reads as
Modbus/TCP: the port hint notes exactly those that read the whole input
image or write the whole output image, with the C plugin (its front end's
verdict, then the decoder's) and without it (the decoder's alone), each
against the verdict the contract gives."""
import struct
import subprocess

from conftest import FORBIDDEN
from modbus_testlib import Traffic
from seam_testlib import CONTRACT

PORT = 5021  # (no dissector sits on it)


def requests():
    """(function code, PDU, (start, count), (write start, write count) or None) per case."""
    c = CONTRACT
    hold, regs = c["MB_INPUT_HOLDING_FIRST"], c["MB_INPUT_REGS"]
    in_reg, in_bit, bits = c["MB_INPUT_REG_FIRST"], c["MB_INPUT_BIT_FIRST"], c["MB_INPUT_BITS"]
    out, out_regs, cmd_regs = c["MB_OUTPUT_REG_FIRST"], c["MB_OUTPUT_REGS"], c["MB_OUTPUT_COMMANDS_REGS"]
    around = (lambda v: [x for x in (v - 1, v, v + 1) if x >= 0])  # noqa: E731
    cases = []

    def read(fc, start, count):
        cases.append((fc, struct.pack(">BHH", fc, start, count), (start, count), None))

    def write(fc, start, count):
        data = bytes((count + 7) // 8) if fc == 15 else bytes(2 * count)
        cases.append((fc, struct.pack(">BHHB", fc, start, count, len(data)) + data, None, (start, count)))

    def read_write(rstart, rcount, wstart, wcount):
        data = bytes(2 * wcount)
        cases.append((23, struct.pack(">BHHHHB", 23, rstart, rcount, wstart, wcount, len(data)) + data,
                      (rstart, rcount), (wstart, wcount)))

    for start in around(in_bit):
        for count in around(bits):
            read(1, start, count)
            read(2, start, count)
    for start in around(hold):
        for count in around(regs) + [regs + 2]:
            read(3, start, count)
            read_write(start, count, out + 200, 1)
    read(3, out, out_regs)
    for start in around(in_reg):
        for count in around(regs):
            read(4, start, count)
    for start in around(out):
        for count in around(cmd_regs) + around(out_regs):
            write(16, start, count)
            write(15, start, count * 16)
            read_write(out + 200, 1, start, count)
    return cases


def is_evidence(fc, reads, writes):
    """The verdict of the contract: the whole input image read, the whole output image written."""
    c = CONTRACT

    def covers(rng, first, n):
        return rng is not None and rng[0] <= first and rng[0] + rng[1] >= first + n

    if fc == 2 and covers(reads, c["MB_INPUT_BIT_FIRST"], c["MB_INPUT_BITS"]):
        return True
    if fc in (3, 23) and covers(reads, c["MB_INPUT_HOLDING_FIRST"], c["MB_INPUT_REGS"]):
        return True
    if fc == 4 and covers(reads, c["MB_INPUT_REG_FIRST"], c["MB_INPUT_REGS"]):
        return True
    return fc in (16, 23) and writes is not None and writes[0] == c["MB_OUTPUT_REG_FIRST"] \
        and writes[1] in (c["MB_OUTPUT_REGS"], c["MB_OUTPUT_COMMANDS_REGS"])


def test_both_sides_note_the_requests_the_contract_names(tshark, work_dir):
    traffic = Traffic()
    frames = {}
    for fc, pdu, reads, writes in requests():
        mb, _ = traffic.client(server_port=PORT)
        mb.tid = 1
        frames[mb.conn.client_send(traffic.t + 0.001, mb.adu(pdu))] = (fc, reads, writes)
        traffic.done(traffic.t + 0.001)
    cap = traffic.write(work_dir, "evidence.pcap")
    want = sorted(n for n, case in frames.items() if is_evidence(*case))
    # (the cases hold both verdicts of every function code that can carry evidence)
    assert {frames[n][0] for n in want} == {2, 3, 4, 16, 23} and len(want) < len(frames)
    got = {}
    for mode in ("C plugin", "Lua alone"):
        env = {k: v for k, v in tshark.env.items() if k != "VRSHARK_NO_C_PLUGIN"}
        if mode == "Lua alone":
            env["VRSHARK_NO_C_PLUGIN"] = "1"
        proc = subprocess.run([tshark.cmd, "-n", "-r", str(cap), "-Y", "eclink_modbus.candidate", "-T", "fields",
                               "-e", "frame.number"], env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr
        assert not any(bad in proc.stdout + proc.stderr for bad in FORBIDDEN)
        got[mode] = [int(n) for n in proc.stdout.split()]
    assert got == {"C plugin": want, "Lua alone": want}

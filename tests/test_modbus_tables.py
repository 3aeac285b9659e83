"""What Wireshark's Modbus dissector offers a Lua plugin that wants to see only
the register accesses an EC-Link BU makes (function codes 3, 4, 6, 16, 23),
instead of taking TCP port 502 (the Lua-only install's carrier, which makes
every Modbus/TCP PDU enter Lua: docs/quality.md, "Foreign Modbus/TCP in the
Lua plugins alone").

4.0 and 4.4 have no table keyed by function code. 4.6 has `modbus.func_code`,
but modbus tries it only for the codes it does not decode in full itself
(UMAS, 90, is its user; 4.6.9 also hands it 23 and 100): the reads and
writes of registers (3, 4, 6, 16) never reach it, so a plugin there would
miss most of a BU's traffic. The test pins that down on the Wireshark it
runs on: a version that hands those codes to the table fails here, and the
carrier can then move there.
"""
import struct

from tools.capgen.frames import TcpConnection
from tools.capgen.pcap import Capture

PROBE = r"""
local out = io.open(%(out)r, "w")
local ok, t = pcall(DissectorTable.get, "modbus.func_code")
if not ok or not t then
    out:write("no table\n")
    out:close()
    return
end
local p = Proto("fcprobe", "modbus.func_code probe")
function p.dissector(tvb, pinfo)
    out:write(string.format("frame %%d\n", pinfo.number))
    out:flush()
    return 0
end
for _, fc in ipairs({ 3, 4, 6, 16, 23, 100 }) do t:add(fc, p) end
"""

# One request a function code: 3 and 4 (read registers), 6 and 16 (write),
# 23 (read/write), 100 (a code modbus does not decode).
REQUESTS = [
    (3, struct.pack(">HH", 0, 2)),
    (4, struct.pack(">HH", 0, 2)),
    (6, struct.pack(">HH", 0, 5)),
    (16, struct.pack(">HHB", 0, 1, 2) + b"\x00\x05"),
    (23, struct.pack(">HHHHB", 0, 1, 0, 1, 2) + b"\x00\x05"),
    (100, b"\x01\x02"),
]


def _capture(path):
    cap = Capture()
    conn = TcpConnection(cap, "10.0.0.1", 40000, "10.0.0.2", 502)
    conn.handshake(1.0)
    frames = {}
    for i, (fc, body) in enumerate(REQUESTS):
        pdu = bytes([1, fc]) + body
        frames[fc] = conn.client_send(1.1 + i * 0.1, struct.pack(">HHH", i + 1, 0, len(pdu)) + pdu)
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    return frames


def test_no_modbus_table_sees_only_register_accesses(tshark, work_dir, lua_probe):
    cap = work_dir / "modbus_codes.pcap"
    frames = _capture(cap)
    lines = lua_probe(PROBE, capture=cap, args=())
    text = tshark.verbose(cap)
    # modbus decodes every request itself (the probe takes nothing)
    for name in ("Read Holding Registers", "Read Input Registers", "Write Single Register",
                 "Write Multiple Registers"):
        assert name in text
    if lines == ["no table"]:
        return          # 4.0, 4.4: nothing keyed by function code
    code_of = {n: fc for fc, n in frames.items()}
    seen = {code_of[int(line.split()[1])] for line in lines}
    assert 100 in seen, "the table is not tried for a code modbus does not decode: %s" % sorted(seen)
    # the register reads and writes a BU is polled with never reach it
    assert not seen & {3, 4, 6, 16}, "modbus.func_code now sees function codes %s" % sorted(seen)

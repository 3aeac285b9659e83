"""What EC-Link over Modbus/TCP keeps of a plain ADU (request and response
frames, response time, PCI or PCO age, range, acceptance) is packed into
strings once the capture has moved past a chunk of 1,024 frames
(lua/eclink_modbus.lua, flat records; lua/vrshark/framemap.luam): the
second pass (tshark -2, a click in Wireshark) reads such frames back from
those strings and shows what one pass shows, times to the microsecond."""
from conftest import assert_fields
from modbus_testlib import Traffic, bu_connection

FIELDS = ["eclink_modbus.request_in", "eclink_modbus.time", "eclink_modbus.pci_age", "eclink_modbus.pco_age",
          "eclink_modbus.accepted_in", "eclink_modbus.table", "eclink.pci", "eclink.pco", "_ws.col.Info",
          "_ws.expert.message"]


def test_second_pass_reads_packed_flat_records(tshark, work_dir):
    # 1,500 reads and writes every 20 ms (6,003 frames); the controller stops
    # polling for 0.7 s after read 800 (a poll gap: a record that stays a table)
    traffic = Traffic()
    jitter = [0.0] * 800 + [0.7] * 700
    _, reads = bu_connection(traffic, {"bu_state": 0x11}, 1500, 0.02, write=True, jitter=jitter)
    path = traffic.write(work_dir, "packed_modbus.pcap")
    one = tshark.frames(path, FIELDS)
    two = tshark.frames(path, FIELDS + ["eclink_modbus.response_in"], two_pass=True)
    assert len(one) == len(two) == 6003
    # one pass and two agree from the frame the connection is recognized in
    # on (the frames before it are shown once it is, on the second pass;
    # a request's response_in is a forward link: the second pass only)
    accepted = int(two[5]["eclink_modbus.accepted_in"])
    assert accepted < 100
    for n in range(accepted, 6004):
        response_in = two[n].pop("eclink_modbus.response_in")
        assert one[n] == two[n], "frame %d" % n
        if two[n]["eclink_modbus.time"] == "" and two[n]["eclink_modbus.table"] != "":
            assert response_in == str(n + 1), "frame %d" % n
    # a read in a packed chunk: its request, its response time, the write after it
    frame, _, pci = reads[1200]
    assert frame > 4096
    assert_fields(two[frame], {"eclink_modbus.request_in": frame - 1, "eclink_modbus.time": "0.003000000",
                               "eclink.pci": pci, "eclink_modbus.accepted_in": two[5]["eclink_modbus.accepted_in"]},
                  "frame %d" % frame)
    assert two[frame + 1]["eclink.pco"] == str(1200 % 256)
    # its PCI age, exact to the microsecond: since the read that first saw this PCI
    since = next(f for f, _, p in reads if p == pci)
    times = tshark.frames(path, ["frame.time_epoch"], display_filter="frame.number == %d || frame.number == %d" % (since, frame))
    age = float(times[frame]["frame.time_epoch"]) - float(times[since]["frame.time_epoch"])
    assert two[frame]["eclink_modbus.pci_age"] == "%.9f" % (round(age * 1e6) / 1e6)
    assert age > 0.05
    gaps = [n for n, r in two.items() if "Input image not read for" in r["_ws.expert.message"]]
    assert gaps == [reads[800][0] - 1]

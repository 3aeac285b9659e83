"""EC-Link over Modbus/TCP: register and bit mapping, byte swap, partial
access, every function code, segments, Decode As. Fields are asserted by
name (tshark.expect / tshark.frames + assert_fields); None means absent.

The heuristic recognizes a connection on a run of a BU's cycles (PCI moving
in the 125 ms cadence, consistent output writes). eclink_modbus_basic is
recognized in its third cycle; the short captures of one access pattern each
(functions, segments, noswap, port5020) end with such a run (capgen
bu_run), so their frames before it are decoded on the second pass: the
tests that look at them use -2 and leave the run out (frame.number < N)."""
from conftest import assert_fields


def by_frame(got, expected, cap):
    """assert_fields for each {frame: {field: value}} of expected."""
    for n, want in expected.items():
        assert n in got, "frame %d is not displayed (%s)" % (n, cap)
        assert_fields(got[n], want, "frame %d" % n)


def test_basic_cycle_values(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    names = ["eclink.image", "eclink.pci", "eclink.cci", "eclink.cai", "eclink.bu_state", "eclink.armed_ru",
             "eclink.ru_state", "eclink.joystick1", "eclink.joystick2", "eclink.joystick4", "eclink.switch1",
             "eclink.switch3", "eclink.switch8", "eclink.encoder", "eclink.cmd_from_ru"]
    got = tshark.frames(cap, names, display_filter="eclink.image == \"input\"", two_pass=True)
    assert sorted(got) == list(range(5, 50, 4))
    by_frame(got, {
        5: {"eclink.image": "input", "eclink.pci": 11, "eclink.cci": 3, "eclink.cai": 7, "eclink.bu_state": "0x11",
            "eclink.armed_ru": "0x1234", "eclink.ru_state": 3, "eclink.joystick1": 500, "eclink.joystick2": -250,
            "eclink.joystick4": 1000, "eclink.switch1": 1, "eclink.switch3": -1, "eclink.switch8": 3,
            "eclink.encoder": 42, "eclink.cmd_from_ru": b"CMD-FROM-RU-03".ljust(16, b"\0").hex()},
        45: {"eclink.bu_state": "0x03", "eclink.armed_ru": "0x1234", "eclink.ru_state": 0},
    }, cap)


def test_output_image_written(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    names = ["eclink.pco", "eclink.cco", "eclink.cao", "eclink.cmd_to_ru", "eclink.periodic_size",
             "eclink.periodic_block", "eclink.spare", "eclink_modbus.table"]
    got = tshark.frames(cap, names, display_filter="eclink.image == \"output\"", two_pass=True)
    assert sorted(got) == list(range(6, 51, 4))
    # in one pass, from the cycle the connection is recognized in (frame 13)
    assert sorted(tshark.frames(cap, ["eclink.pco"], display_filter="eclink.image == \"output\"")) == \
        list(range(14, 51, 4))
    by_frame(got, {6: {"eclink.pco": 21, "eclink.cco": 7, "eclink.cao": 3,
                       "eclink.cmd_to_ru": b"CMD-TO-RU-07".ljust(16, b"\0").hex(), "eclink.periodic_size": 120,
                       "eclink.periodic_block": 0, "eclink.spare": "00",
                       "eclink_modbus.table": "Holding registers 0-111"}}, cap)


def test_request_response_pairing(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    got = tshark.frames(cap, ["eclink_modbus.request_in", "eclink_modbus.time"], display_filter="frame.number <= 15")
    # the connection is recognized in 13 (the third cycle's input image): 5..11 are decoded on the second pass
    assert [n for n, r in got.items() if r["eclink_modbus.request_in"]] == [13, 15]
    got = tshark.frames(cap, ["eclink_modbus.request_in", "eclink_modbus.time"], display_filter="frame.number <= 9",
                        two_pass=True)
    assert [n for n, r in got.items() if r["eclink_modbus.request_in"]] == [5, 7, 9]
    by_frame(got, {n: {"eclink_modbus.request_in": n - 1, "eclink_modbus.time": "0.003000000"} for n in (5, 7, 9)},
             cap)
    # the link from the request forward is known on the second pass
    got2 = tshark.frames(cap, ["eclink_modbus.response_in"], display_filter="frame.number <= 9", two_pass=True)
    assert [n for n, r in got2.items() if r["eclink_modbus.response_in"]] == [6, 8]
    by_frame(got2, {6: {"eclink_modbus.response_in": 7}, 8: {"eclink_modbus.response_in": 9}}, cap)


def test_function_codes(tshark, capture_file):
    cap = capture_file("eclink_modbus_functions.pcap")
    names = ["eclink_modbus.table", "eclink.image", "eclink.covered", "eclink.pci", "eclink.pco", "eclink.cco",
             "eclink.cao", "eclink.periodic_size"]
    got = tshark.frames(cap, names, two_pass=True)
    T, I, C = "eclink_modbus.table", "eclink.image", "eclink.covered"

    def out(table, covered, pco, cco, cao, size):
        return {T: table, I: "output", C: covered, "eclink.pci": None, "eclink.pco": pco, "eclink.cco": cco,
                "eclink.cao": cao, "eclink.periodic_size": size}
    by_frame(got, {
        5: {T: "Input registers 0-31", I: "input", C: None, "eclink.pci": 1},
        7: {T: "Holding registers 2048-2079", I: "input", C: None, "eclink.pci": 1},
        9: {T: "Input registers 2-5", I: "input", C: "4-11 of 64"},
        11: out("Holding registers 10-11", "20-23 of 224", None, None, None, 0),
        13: {T: "Discrete inputs 0-511", I: "input", C: None, "eclink.pci": 1},
        15: {T: "Discrete inputs 163-192", I: "input", C: "21-23 of 64"},
        17: out("Coils 0-31", "0-3 of 224", 1, 5, 2, None),
        18: {T: "Coils 12-12", I: None},
        20: out("Holding registers 1-1", "2-3 of 224", None, None, 2, None),
        22: out("Coils 0-15", "0-1 of 224", 1, 5, None, None),
        24: out("Holding registers 0-111", None, 1, 5, 2, 0),
        # the request decodes the image it writes (holding registers 0-9), the response the one it reads
        26: out("Holding registers 0-9 (written)", "0-19 of 224", 1, 5, 2, None),
        27: out("Holding registers 0-3", "0-7 of 224", 1, 5, 2, None),
        29: {T: "Holding registers 200-209", I: None},
        31: {T: "Holding registers 2100-2103", I: None},
    }, cap)


def test_partial_access_names_cut_fields(tshark, capture_file):
    cap = capture_file("eclink_modbus_functions.pcap")
    got = tshark.frames(cap, ["eclink.cut", "eclink_modbus.bits", "eclink.vlaps", "eclink.unarmed_rus",
                              "eclink.eg_link_status"], two_pass=True)
    by_frame(got, {
        9: {"eclink.cut": "cmd_from_ru (image bytes 4-19; 4-11 present)"},
        15: {"eclink.cut": None, "eclink_modbus.bits": "input image byte 20 bits 3-7 (bu_state),"
                                                      "input image byte 24 bits 0-0 (ec_link_status)",
             "eclink.vlaps": 1, "eclink.unarmed_rus": 0, "eclink.eg_link_status": 1},
        18: {"eclink_modbus.bits": "output image byte 1 bits 4-4 (cco)"},
        27: {"eclink.cut": "cmd_to_ru (image bytes 4-19; 4-7 present)"},
    }, cap)
    exp = tshark.experts(cap, two_pass=True)
    assert exp[9] == ["Image bytes 4-11 of 64 present; cut: cmd_from_ru"]


def test_exception_response(tshark, capture_file):
    cap = capture_file("eclink_modbus_functions.pcap")
    tshark.expect(cap, 29, {"eclink_modbus.request_in": 28, "modbus.exception_code": 2}, two_pass=True)


def test_segments(tshark, capture_file):
    cap = capture_file("eclink_modbus_segments.pcap")
    names = ["eclink.image", "eclink.pci", "eclink.ru_state", "eclink_modbus.request_in", "eclink_modbus.table"]
    got = tshark.frames(cap, names, display_filter="eclink_modbus && frame.number <= 10", two_pass=True)
    assert sorted(got) == [5, 6, 7, 8, 10]
    by_frame(got, {
        5: {"eclink.image": "input", "eclink.pci": 1, "eclink.ru_state": 3, "eclink_modbus.request_in": 4,
            "eclink_modbus.table": "Input registers 0-31"},
        6: {"eclink.image": "output", "eclink.pci": None, "eclink.ru_state": None, "eclink_modbus.request_in": None,
            "eclink_modbus.table": "Input registers 0-31,Holding registers 0-9"},
        7: {"eclink.image": "input", "eclink.pci": 2, "eclink.ru_state": 2, "eclink_modbus.request_in": "6,6",
            "eclink_modbus.table": "Input registers 0-31,Holding registers 0-9"},
        8: {"eclink.image": None, "eclink_modbus.table": "Input registers 0-31"},
        10: {"eclink.image": "input", "eclink.pci": 3, "eclink.ru_state": 4, "eclink_modbus.request_in": 8,
             "eclink_modbus.table": "Input registers 0-31"},
    }, cap)
    assert tshark.experts(cap, two_pass=True)[10] == ["RU stopped: ES-Link relays open"]


def test_segments_without_tcp_reassembly(tshark, capture_file):
    cap = capture_file("eclink_modbus_segments.pcap")
    got = tshark.frames(cap, ["eclink.pci"], display_filter="eclink.image && frame.number <= 10",
                        prefs={"tcp.desegment_tcp_streams": "FALSE"}, two_pass=True)
    assert sorted(got) == [5, 6, 7]
    by_frame(got, {5: {"eclink.pci": 1}, 6: {"eclink.pci": None}, 7: {"eclink.pci": 2}}, cap)


def test_swap_off(tshark, capture_file):
    cap = capture_file("eclink_modbus_noswap.pcap")
    names = ["eclink.pci", "eclink.armed_ru", "eclink.joystick1", "eclink.joystick2", "eclink.pco",
             "eclink.periodic_size", "eclink.periodic_block"]
    got = tshark.frames(cap, names, display_filter="eclink.image && frame.number <= 7",
                        prefs={"eclink_modbus.swap": "FALSE"}, two_pass=True)
    assert sorted(got) == [5, 6]
    by_frame(got, {
        5: {"eclink.pci": 9, "eclink.armed_ru": "0x0102", "eclink.joystick1": -1000, "eclink.joystick2": 1,
            "eclink.pco": None},
        6: {"eclink.pci": None, "eclink.pco": 5, "eclink.periodic_size": 300, "eclink.periodic_block": 1},
    }, cap)
    # with the default (swapped) view the same device is not recognized
    assert tshark.frames(cap, ["eclink.image"], display_filter="eclink") == {}


def test_decode_as_other_port(tshark, capture_file):
    cap = capture_file("eclink_modbus_port5020.pcap")
    assert tshark.frames(cap, ["eclink.image"], display_filter="eclink") == {}
    got = tshark.frames(cap, ["eclink.pci", "eclink.pco", "modbus.func_code"],
                        display_filter="eclink.image && frame.number <= 7",
                        decode_as=["tcp.port==5020,eclink_modbus"], two_pass=True)
    assert sorted(got) == [5, 6]
    by_frame(got, {5: {"eclink.pci": 1, "eclink.pco": None, "modbus.func_code": 4},
                   6: {"eclink.pci": None, "eclink.pco": 1, "modbus.func_code": 16}}, cap)


def test_port_preference(tshark, capture_file):
    cap = capture_file("eclink_modbus_port5020.pcap")
    got = tshark.frames(cap, ["eclink.pci"], display_filter="eclink.image && frame.number <= 7",
                        prefs={"eclink_modbus.port": "5020"}, two_pass=True)
    assert sorted(got) == [5, 6]
    by_frame(got, {5: {"eclink.pci": 1}, 6: {"eclink.pci": None}}, cap)

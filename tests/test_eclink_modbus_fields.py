"""EC-Link over Modbus/TCP: register and bit mapping, byte swap, partial
access, every function code, segments, Decode As.

These short captures are recognized in their first output write (input
image + output image), after their first input image: frames before it are
decoded on the second pass, so the tests that look at them use -2."""
import pytest

CONN = {}


def rows(tshark, cap, names, **kw):
    return tshark.fields(cap, ["frame.number"] + names, **kw)


def test_basic_cycle_values(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    r = {int(x[0]): x[1:] for x in rows(tshark, cap, [
        "eclink.image", "eclink.pci", "eclink.cci", "eclink.cai", "eclink.bu_state", "eclink.armed_ru",
        "eclink.ru_state", "eclink.joystick1", "eclink.joystick2", "eclink.joystick4", "eclink.switch1",
        "eclink.switch3", "eclink.switch8", "eclink.encoder", "eclink.cmd_from_ru"],
        display_filter="eclink.image == \"input\"", two_pass=True)}
    assert sorted(r) == list(range(5, 50, 4))
    assert r[5] == ["input", "11", "3", "7", "0x11", "0x1234", "3", "500", "-250", "1000", "1", "-1", "3",
                    "42", b"CMD-FROM-RU-03".ljust(16, b"\0").hex()]
    assert r[45][4:7] == ["0x03", "0x1234", "0"]


def test_output_image_written(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    r = rows(tshark, cap, ["eclink.pco", "eclink.cco", "eclink.cao", "eclink.cmd_to_ru", "eclink.periodic_size",
                           "eclink.periodic_block", "eclink.spare", "eclink_modbus.table"],
             display_filter="eclink.image == \"output\"")
    assert [x[0] for x in r] == [str(n) for n in range(6, 51, 4)]
    assert r[0][1:] == ["21", "7", "3", b"CMD-TO-RU-07".ljust(16, b"\0").hex(), "120", "0", "00",
                        "Holding registers 0-111"]


def test_request_response_pairing(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    r = rows(tshark, cap, ["eclink_modbus.request_in", "eclink_modbus.time"], display_filter="frame.number <= 9")
    # the connection is recognized in 6 (the first output write): 5 is decoded on the second pass
    assert [x for x in r if x[1]] == [["7", "6", "0.003000000"], ["9", "8", "0.003000000"]]
    r = rows(tshark, cap, ["eclink_modbus.request_in", "eclink_modbus.time"], display_filter="frame.number <= 9",
             two_pass=True)
    assert [x for x in r if x[1]] == [["5", "4", "0.003000000"], ["7", "6", "0.003000000"],
                                      ["9", "8", "0.003000000"]]
    # the link from the request forward is known on the second pass
    r2 = rows(tshark, cap, ["eclink_modbus.response_in"], display_filter="frame.number <= 9", two_pass=True)
    assert [x for x in r2 if x[1]] == [["6", "7"], ["8", "9"]]


def test_function_codes(tshark, capture_file):
    cap = capture_file("eclink_modbus_functions.pcap")
    r = {int(x[0]): x[1:] for x in rows(tshark, cap, ["eclink_modbus.table", "eclink.image", "eclink.covered",
                                                      "eclink.pci", "eclink.pco", "eclink.cco", "eclink.cao",
                                                      "eclink.periodic_size"], two_pass=True)}
    assert r[5][:4] == ["Input registers 0-31", "input", "", "1"]
    assert r[7][:4] == ["Holding registers 2048-2079", "input", "", "1"]
    assert r[9][:3] == ["Input registers 2-5", "input", "4-11 of 64"]
    assert r[11] == ["Holding registers 10-11", "output", "20-23 of 224", "", "", "", "", "0"]
    assert r[13][:4] == ["Discrete inputs 0-511", "input", "", "1"]
    assert r[15][:3] == ["Discrete inputs 163-192", "input", "21-23 of 64"]
    assert r[17] == ["Coils 0-31", "output", "0-3 of 224", "", "1", "5", "2", ""]
    assert r[18][:2] == ["Coils 12-12", ""]
    assert r[20] == ["Holding registers 1-1", "output", "2-3 of 224", "", "", "", "2", ""]
    assert r[22] == ["Coils 0-15", "output", "0-1 of 224", "", "1", "5", "", ""]
    assert r[24] == ["Holding registers 0-111", "output", "", "", "1", "5", "2", "0"]
    # the request decodes the image it writes (holding registers 0-9), the response the one it reads
    assert r[26] == ["Holding registers 0-9 (written)", "output", "0-19 of 224", "", "1", "5", "2", ""]
    assert r[27] == ["Holding registers 0-3", "output", "0-7 of 224", "", "1", "5", "2", ""]
    assert r[29][:2] == ["Holding registers 200-209", ""]
    assert r[31][:2] == ["Holding registers 2100-2103", ""]


def test_partial_access_names_cut_fields(tshark, capture_file):
    cap = capture_file("eclink_modbus_functions.pcap")
    r = {int(x[0]): x[1:] for x in rows(tshark, cap, ["eclink.cut", "eclink_modbus.bits", "eclink.vlaps",
                                                      "eclink.unarmed_rus", "eclink.eg_link_status"],
                                         two_pass=True)}
    assert r[9][0] == "cmd_from_ru (image bytes 4-19; 4-11 present)"
    assert r[15] == ["", "input image byte 20 bits 3-7 (bu_state),input image byte 24 bits 0-0 (ec_link_status)",
                     "1", "0", "1"]
    assert r[18][1] == "output image byte 1 bits 4-4 (cco)"
    assert r[27][0] == "cmd_to_ru (image bytes 4-19; 4-7 present)"
    exp = tshark.experts(cap, two_pass=True)
    assert exp[9] == ["Image bytes 4-11 of 64 present; cut: cmd_from_ru"]


def test_exception_response(tshark, capture_file):
    cap = capture_file("eclink_modbus_functions.pcap")
    r = rows(tshark, cap, ["eclink_modbus.request_in", "modbus.exception_code"], display_filter="frame.number == 29")
    assert r == [["29", "28", "2"]]


def test_segments(tshark, capture_file):
    cap = capture_file("eclink_modbus_segments.pcap")
    r = rows(tshark, cap, ["eclink.image", "eclink.pci", "eclink.ru_state", "eclink_modbus.request_in",
                           "eclink_modbus.table"], display_filter="eclink_modbus", two_pass=True)
    assert r == [
        ["5", "input", "1", "3", "4", "Input registers 0-31"],
        ["6", "output", "", "", "", "Input registers 0-31,Holding registers 0-9"],
        ["7", "input", "2", "2", "6,6", "Input registers 0-31,Holding registers 0-9"],
        ["8", "", "", "", "", "Input registers 0-31"],
        ["10", "input", "3", "4", "8", "Input registers 0-31"],
    ]
    assert tshark.experts(cap)[10] == ["RU stopped: ES-Link relays open"]


def test_segments_without_tcp_reassembly(tshark, capture_file):
    cap = capture_file("eclink_modbus_segments.pcap")
    r = rows(tshark, cap, ["eclink.pci"], display_filter="eclink.image",
             prefs={"tcp.desegment_tcp_streams": "FALSE"}, two_pass=True)
    assert r == [["5", "1"], ["6", ""], ["7", "2"]]


def test_swap_off(tshark, capture_file):
    cap = capture_file("eclink_modbus_noswap.pcap")
    names = ["eclink.pci", "eclink.armed_ru", "eclink.joystick1", "eclink.joystick2", "eclink.pco",
             "eclink.periodic_size", "eclink.periodic_block"]
    r = rows(tshark, cap, names, display_filter="eclink.image", prefs={"eclink_modbus.swap": "FALSE"},
             two_pass=True)
    assert r == [["5", "9", "0x0102", "-1000", "1", "", "", ""], ["6", "", "", "", "", "5", "300", "1"]]
    # with the default (swapped) view the same device is not recognized
    assert tshark.field(cap, "eclink.image", display_filter="eclink") == []


def test_decode_as_other_port(tshark, capture_file):
    cap = capture_file("eclink_modbus_port5020.pcap")
    assert tshark.field(cap, "eclink.image", display_filter="eclink") == []
    r = rows(tshark, cap, ["eclink.pci", "eclink.pco", "modbus.func_code"], display_filter="eclink.image",
             decode_as=["tcp.port==5020,eclink_modbus"], two_pass=True)
    assert r == [["5", "1", "", "4"], ["6", "", "1", "16"]]


def test_port_preference(tshark, capture_file):
    cap = capture_file("eclink_modbus_port5020.pcap")
    r = rows(tshark, cap, ["eclink.pci"], display_filter="eclink.image", prefs={"eclink_modbus.port": "5020"},
             two_pass=True)
    assert r == [["5", "1"], ["6", ""]]

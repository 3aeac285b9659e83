"""IO lists as spreadsheets really save them, and the mistakes people make in
them: German Excel (";" and decimal commas, Windows-1252), Excel's default
CSV on many Windows machines (Windows-1252), "Unicode text" (UTF-16, tab
separated) decode exactly like the UTF-8 file; every mistake gets a message
that says what is wrong and how to fix it, and the rest still loads."""
import csv
import io
import os
import shutil

import pytest

from conftest import CAPTURES
from io_testlib import CRANE_CSV, io_tshark, problems, world_folder, write

CRANE_CAPTURES = ["crane_eglink.pcap", "crane_mcmb2.pcap", "crane_eclink_modbus.pcap", "crane_eclink_pnio.pcap"]


def export(delimiter, decimal_comma, encoding):
    """examples/crane/crane.csv as a spreadsheet saves it."""
    rows = list(csv.reader(io.StringIO(CRANE_CSV.read_text(encoding="utf-8"))))
    header = rows[0]
    out = io.StringIO()
    writer = csv.writer(out, delimiter=delimiter, lineterminator="\r\n")
    for k, row in enumerate(rows):
        if k and decimal_comma:
            row = [cell.replace(".", ",") if header[i] in ("scale", "offset") else cell for i, cell in enumerate(row)]
        writer.writerow(row)
    return out.getvalue().encode(encoding)


EXPORTS = {
    "german-excel": (";", True, "cp1252"),       # CSV (Trennzeichen-getrennt)
    "windows-1252": (",", False, "cp1252"),      # CSV (comma delimited) on a Western Windows
    "utf-16-text": ("\t", True, "utf-16"),       # Unicode-Text: UTF-16LE with its BOM, tabs
}


@pytest.fixture(scope="module")
def utf8_text(conf_dir):
    folder = world_folder()
    shutil.copy(CRANE_CSV, folder / "crane.csv")
    (folder / "crane.csv").chmod(0o644)
    t = io_tshark(conf_dir, folder)
    yield {name: t.verbose(CAPTURES / name, two_pass=True) for name in CRANE_CAPTURES}
    shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("kind", sorted(EXPORTS))
def test_spreadsheet_exports_decode_like_the_utf8_file(conf_dir, utf8_text, kind):
    data = export(*EXPORTS[kind])
    if kind != "utf-16-text":
        assert "°".encode("cp1252") in data and "°".encode("utf-8") not in data
    folder = world_folder()
    try:
        path = folder / "crane.csv"
        path.write_bytes(data)
        path.chmod(0o644)
        t = io_tshark(conf_dir, folder)
        proc = t.run(["-n", "-r", str(CAPTURES / "crane_eglink.pcap")])
        assert problems(proc) == []
        for name in CRANE_CAPTURES:
            text = t.verbose(CAPTURES / name, two_pass=True)
            assert text == utf8_text[name], (kind, name)
        assert "Slew angle (°)" in utf8_text["crane_eglink.pcap"]
        t.expect(CAPTURES / "crane_eglink.pcap", 10, {"vrshark.io.load": 52.3, "vrshark.io.hook_height": 44})
    finally:
        shutil.rmtree(folder, ignore_errors=True)


MISTAKES = "\n".join([
    "area,byte,bit,type,name,label,unit,scale,offset,values,fault,severity,device",  # 1
    "cmd.from_ru,6,,u8,op,Operator,,,,,,,",                                           # 2 good
    "periodic.to_ru,0,9-3,u16le,bits,,,,,,,,",                                        # 3 bit range downwards
    "mcmb2.up,0,,u8,term,,,,,,,,terminal=99",                                         # 4 terminal 1-15
    "cmd.from_ru,7,,u8,srv,,,,,,,,server=1.2.3",                                      # 5 not an address
    "cmd.to_ru,0,,u8,code,,,,,0=a;0=b,,,",                                            # 6 value named twice
    "cmd.to_ru,1,,u8,level,,,,,,300,,",                                               # 7 fault beyond u8
    "cmd.to_ru,2,,u8,rterm,,,,,,,,terminal=3",                                        # 8 no terminal there
    "mcmb2.up,0,,ascii:300,long,,,,,,,,",                                             # 9 longer than the area
    "cmd.to_ru,3,,u8,op\0x,,,,,,,,",                                                  # 10 NUL in the name
    "periodic.to_ru,6,0,bool,alarm,Alarm,,,,No;Yes,1,,",                              # 11 good: bool names in order
    "periodic.to_ru,6,1,bool,other,,,,,Off;On;Maybe,,,",                              # 12 three names on a bool
]) + "\n"

MISTAKE_MESSAGES = [
    "mistakes.csv line 3: bit range '9-3' runs from high to low; fix: write the lowest bit first: 3-9",
    "mistakes.csv line 4: terminal=99 is outside 1-15; fix: write a terminal from 1 to 15",
    "mistakes.csv line 5: bad IP address '1.2.3' in column device; fix: write the BU's IP address, such as "
    "server=192.168.2.41",
    "mistakes.csv line 6: value 0 is named twice in column values ('0=a;0=b'); fix: name each value once",
    "mistakes.csv line 7: fault value 300 is outside the u8 (0 to 255); fix: give fault values the field can "
    "hold (raw values, before scaling)",
    "mistakes.csv line 8: device key 'terminal' never matches in cmd.to_ru: its frames tell origin, frame_id, "
    "server; fix: use origin=..., or leave the device empty",
    "mistakes.csv line 9: type ascii:300 is longer than the mcmb2.up area (254 bytes); fix: use at most "
    "ascii:254, starting at byte 0",
    "mistakes.csv line 10: bad name 'op\\x00x' (it holds a control character); fix: use lower-case letters, "
    "digits and _ only, starting with a letter (it becomes vrshark.io.<name>)",
    "mistakes.csv line 12: bad value name 'Off' in column values; fix: write 0=No;1=Yes, or the two names in "
    "order: No;Yes",
    "other.csv line 2: 'op2' overlaps 'op' (mistakes.csv line 2) in cmd.from_ru; fix: check byte, bit and type "
    "of both rows; two fields may not share a bit of the same area and device, in one file or several",
    "unreadable.csv: the file cannot be read (Permission denied); fix: make it readable by the user running "
    "Wireshark",
    "z-folder.csv: this is a folder, not a description file; fix: move the folder, or rename it so that it "
    "does not end in .csv",
]


@pytest.fixture
def mistakes(conf_dir, work_dir):
    write(work_dir, "mistakes.csv", MISTAKES)
    write(work_dir, "other.csv", "area,byte,type,name\ncmd.from_ru,6,u8,op2\ncmd.from_ru,8,u8,free\n")
    unreadable = write(work_dir, "unreadable.csv", "area,byte,type,name\ncmd.to_ru,9,u8,secret\n")
    unreadable.chmod(0)
    (work_dir / "z-folder.csv").mkdir()
    (work_dir / "z-folder.csv").chmod(0o755)
    return io_tshark(conf_dir, work_dir)


def test_each_mistake_named_with_its_fix(mistakes):
    if os.geteuid() != 0 and os.access(mistakes.env["VRSHARK_IO_DIR"] + "/unreadable.csv", os.R_OK):
        pytest.skip("this user reads files of mode 000")
    proc = mistakes.run(["-n", "-r", str(CAPTURES / "crane_eglink.pcap")])
    assert problems(proc) == MISTAKE_MESSAGES
    assert "Lua Error" not in proc.stdout + proc.stderr


def test_the_rest_still_loads(mistakes):
    fields = mistakes.run(["-G", "fields"], allow_errors=True).stdout
    registered = sorted(ln.split("\t")[2] for ln in fields.splitlines() if "\tvrshark.io." in ln)
    assert registered == ["vrshark.io.alarm", "vrshark.io.free", "vrshark.io.op"]
    mistakes.expect(CAPTURES / "crane_eglink.pcap", 2, {"vrshark.io.op": 7})


def test_bool_names_in_order(conf_dir, work_dir):
    """values "No;Yes" on a bool names 0 and 1, as "0=No;1=Yes" does (docs/io.md)."""
    texts = {}
    for name, values in (("a", "No;Yes"), ("b", "0=No;1=Yes")):
        folder = work_dir / name
        folder.mkdir()
        folder.chmod(0o755)
        write(folder, "wind.csv", "area,byte,bit,type,name,label,values\n"
                                  "periodic.to_ru,6,1,bool,wind,Wind alarm,%s\n" % values)
        texts[name] = io_tshark(conf_dir, folder).verbose(CAPTURES / "crane_eglink.pcap")
    assert texts["a"] == texts["b"]
    assert "= Wind alarm: No" in texts["a"] and "= Wind alarm: Yes" in texts["a"]

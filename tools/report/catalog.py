"""The expert fields the report reads, by name, with their severity and role.

tshark -T fields prints an expert field (FT_NONE) as 1 on the frames that
carry it, so the report asks for each one by name and never reads message
texts; details.py adds the value a finding names from the value fields.

Roles:
  finding   listed in the timeline; bursts of it collapse into one line
  relays    means "ES-Link relays open": shown as the relay condition the
            model derives from the BU and RU states, not repeated per frame
  state     a state change the model derives from the state fields itself
  stall     a counter that stopped moving: the model measures the stall
  gap       EG-Link VRPI/VRPO missing or late: the model measures the gap
  poll_gap  a controller that stopped reading: the model measures the gap
            between the frames itself (not read from the expert)
  failed    a command not acknowledged in time: one entry per command, never
            a burst; {of} in its text is " of frame N", the command's frame
  deadline  the note that a command's deadline passed: listed only when its
            command's failure is not (one entry per failed command)
  candidate traffic that looks like a device's but was not decoded: the
            model lists the candidate with the setting that decodes it
Chat-level experts (acknowledged commands, layouts learned, partial access)
are not asked for: they are no findings.

The severities are the dissectors' (docs/findings.md "How findings read" is their
one source; tests/test_report_catalog.py checks this list against it and
against the captures, and docs/report.md against this list), except
PROMOTED: a candidate the dissector notes is a warning in the report, so
that `--fail-on warn` catches traffic vrshark could not decode.
"""

NOTE, WARNING, ERROR = "note", "warning", "error"
LEVELS = {NOTE: 1, WARNING: 2, ERROR: 3}

# name: (severity, role, what the timeline says)
EXPERTS = {
    # EG-Link, single packet
    "eglink.too_short": (ERROR, "finding", "packet too short for EG-Link"),
    "eglink.size.mismatch": (ERROR, "finding", "header Size disagrees with the UDP length"),
    "eglink.size.invalid": (ERROR, "finding", "payload size wrong for the packet type"),
    "eglink.type.unknown": (WARNING, "finding", "unknown packet type"),
    "eglink.revision.unknown": (WARNING, "finding", "unknown layout revision"),
    "eglink.origin.nonzero": (WARNING, "finding", "origin not 0 in a controller packet"),
    "eglink.origin.zero": (WARNING, "finding", "origin 0 in a BU packet"),
    "eglink.spare.nonzero": (WARNING, "finding", "header spare not 0"),
    "eglink.payload_spare.nonzero": (WARNING, "finding", "payload spare not 0"),
    "eglink.crc.bad": (ERROR, "finding", "bad CRC"),
    "eglink.crc.variant": (WARNING, "finding", "CRC of another variant: set the CRC preference"),
    "eglink.bu_state.relays_open": (WARNING, "relays", "ES-Link relays open"),
    "eglink.bu_state.unknown": (ERROR, "finding", "undefined BU state"),
    "eglink.link_status.unknown": (ERROR, "finding", "undefined link status"),
    "eglink.vlaps.range": (ERROR, "finding", "more than 3 VLAPs"),
    "eglink.ru_state.stopped": (WARNING, "relays", "RU stopped"),
    "eglink.ru_state.unknown": (ERROR, "finding", "undefined RU state"),
    "eglink.ru_battery.range": (ERROR, "finding", "RU battery above 100 %"),
    "eglink.ru_rssi.range": (ERROR, "finding", "RU RSSI above 100 %"),
    "eglink.flag.invalid": (ERROR, "finding", "flag neither 0 nor 1"),
    "eglink.ru_disabled.unknown": (ERROR, "finding", "undefined RU disabled reason"),
    "eglink.joystick.range": (ERROR, "finding", "joystick outside -1000..1000"),
    "eglink.armed_ru.unarmed_data": (ERROR, "finding", "RU fields not 0 while no RU is armed"),
    # EG-Link conversation analysis. The report reads one pass: a command
    # that failed shows at the packet that saw its deadline pass (the
    # warning naming it), the moment the BU gives up; an older plugin gives
    # there only the deadline note (the warning sits on the command, second
    # pass only).
    "eglink.analysis.serial_gap": (WARNING, "finding", "packets lost"),
    "eglink.analysis.serial_repeat": (WARNING, "finding", "repeated packet"),
    "eglink.analysis.serial_restart": (NOTE, "finding", "sender restarted (serial jumped back)"),
    "eglink.analysis.vrpi_missing": (ERROR, "gap", "VRPI"),
    "eglink.analysis.vrpi_gap": (ERROR, "gap", "VRPI"),
    "eglink.analysis.vrpo_missing": (ERROR, "gap", "VRPO"),
    "eglink.analysis.vrpo_gap": (ERROR, "gap", "VRPO"),
    "eglink.analysis.retransmission": (NOTE, "finding", "command retransmitted"),
    "eglink.analysis.vrci_unacked": (WARNING, "failed",
                                     "VRCI{of} not acknowledged in time: the command failed"),
    "eglink.analysis.vrco_unacked": (WARNING, "failed",
                                     "VRCO{of} not acknowledged in time: the command failed"),
    "eglink.analysis.vrci_deadline": (NOTE, "deadline", "deadline of the VRCI{of} passed"),
    "eglink.analysis.vrco_deadline": (NOTE, "deadline", "deadline of the VRCO{of} passed"),
    "eglink.analysis.late_ack": (WARNING, "finding", "late acknowledgement"),
    "eglink.analysis.bu_state_changed": (NOTE, "state", "BU state changed"),
    "eglink.analysis.origin_changed": (WARNING, "finding", "another origin at the same BU address"),
    "eglink.analysis.shared_group": (WARNING, "finding", "several BUs or controllers on one group and port"),
    "eglink.analysis.join_withdrawn": (NOTE, "finding",
                                       "controller no longer joined to the BU it was alone with"),
    "eglink.analysis.burst_incomplete": (WARNING, "finding", "split VRPO burst incomplete"),
    "eglink.analysis.burst_size": (WARNING, "finding", "VRPO burst size differs from the preference"),
    "eglink.analysis.serial_corrupted": (NOTE, "finding",
                                         "a serial of the gap arrived with a bad CRC or size: not lost"),
    "eglink.analysis.wrong_port": (WARNING, "finding", "controller packet sent to the wrong UDP port"),
    "eglink.analysis.time_backwards": (WARNING, "finding",
                                       "time went backwards (clock step): gap and deadline rules restart"),
    "eglink.cut": (NOTE, "finding", "packet cut by the capture (snaplen): decoded as far as captured"),
    # EG-Link, the rules of TS-0006
    "eglink.link_status.passive": (WARNING, "finding", "link status Passive where it is not allowed"),
    "eglink.ru_state.disarmed": (NOTE, "finding", "RU state Disarmed (used inside the BU only) on the wire"),
    "eglink.fields_disagree": (WARNING, "finding", "status fields contradict each other"),
    "eglink.link_status.fault": (WARNING, "finding", "a link reports a fault"),
    "eglink.analysis.vrpo_number": (WARNING, "finding", "VRPO packet number out of the controller's numbering"),
    "eglink.analysis.vrpo_not_full": (WARNING, "finding", "VRPO packet not full though not the last of its burst"),
    "eglink.analysis.not_resent": (WARNING, "finding", "unacknowledged command not resent within 100 ms"),
    "eglink.analysis.command_id_sequence": (WARNING, "finding", "Command ID not the previous one + 1"),
    "eglink.analysis.vrpo_interval": (NOTE, "finding", "VRPO interval outside the recommended 50 to 200 ms"),
    "eglink.analysis.burst_spread": (NOTE, "finding", "packets of a split VRPO burst spread out"),
    "eglink.analysis.resend_interval": (NOTE, "finding", "command resent at another interval than 100 ms"),
    "eglink.analysis.resent_after_ack": (NOTE, "finding", "command resent after its acknowledgement"),
    "eglink.analysis.resent_after_deadline": (NOTE, "finding", "command resent after its timeout"),
    "eglink.analysis.revision_ignored": (NOTE, "finding", "packet of another header revision not analysed"),
    # MC-MB2-PN
    "mcmb2.status.undefined": (ERROR, "finding", "undefined status"),
    "mcmb2.slot.status.undefined": (ERROR, "finding", "undefined slot status"),
    "mcmb2.terminal.not_zero": (WARNING, "finding", "terminal bits set in a polled status"),
    "mcmb2.no_valid_data": (WARNING, "finding", "no valid terminal data"),
    "mcmb2.status.e010": (ERROR, "finding", "E010 reported by the base"),
    "mcmb2.data_not_zero": (WARNING, "finding", "data not 0 while the terminal is not present"),
    "mcmb2.uplink_watchdog.stalled": (ERROR, "stall", "uplink watchdog"),
    "mcmb2.downlink_watchdog.stalled": (ERROR, "stall", "downlink watchdog"),
    "mcmb2.uplink_missing": (ERROR, "finding", "no uplink frame within the uplink timeout"),
    "mcmb2.downlink_missing": (ERROR, "finding", "no downlink frame within the downlink timeout"),
    "mcmb2.data_hold_exceeded": (ERROR, "finding", "no frame of a stream within the Connect's data hold time"),
    "mcmb2.frames_lost": (WARNING, "finding", "cyclic frames lost (cycle counter)"),
    "eclink_pnio.input_missing": (ERROR, "finding", "no input frame within 500 ms"),
    "eclink_pnio.output_missing": (ERROR, "finding", "no output frame within 2000 ms"),
    "eclink_pnio.data_hold_exceeded": (ERROR, "finding", "no frame of a stream within the Connect's data hold time"),
    "eclink_pnio.frames_lost": (WARNING, "finding", "cyclic frames lost (cycle counter)"),
    "mcmb2.downlink_watchdog.unwritten": (NOTE, "finding",
                                          "simplex downlink watchdog not written, no E010: the base may not "
                                          "monitor it (mcmb2.simplex_downlink)"),
    "mcmb2.uplink_watchdog.slow": (WARNING, "finding", "uplink watchdog not incremented within 500 ms"),
    "mcmb2.downlink_watchdog.slow": (WARNING, "finding", "downlink watchdog not incremented within 500 ms"),
    "mcmb2.uplink_watchdog.backwards": (WARNING, "finding", "uplink watchdog went backwards"),
    "mcmb2.downlink_watchdog.backwards": (WARNING, "finding", "downlink watchdog went backwards"),
    "mcmb2.uplink_watchdog.jump": (NOTE, "finding", "uplink watchdog moved by more than one"),
    "mcmb2.downlink_watchdog.jump": (NOTE, "finding", "downlink watchdog moved by more than one"),
    "mcmb2.slot.terminal_changed": (NOTE, "state", "slot serves another terminal"),
    "mcmb2.layout_mismatch": (ERROR, "finding", "Y, Z or slots differ from the configured layout"),
    "mcmb2.iops.bad": (WARNING, "finding", "IOPS not GOOD"),
    "mcmb2.iocs.bad": (WARNING, "finding", "IOCS not GOOD"),
    "mcmb2.reserved.not_zero": (WARNING, "finding", "reserved byte not 0"),
    "mcmb2.short": (ERROR, "finding", "C-SDU shorter than the layout"),
    "mcmb2.layout.inferred": (NOTE, "finding", "layout inferred from the cyclic frames (no Connect)"),
    "mcmb2.layout.ambiguous": (NOTE, "finding", "more than one layout fits the cyclic frames"),
    "mcmb2.layout.reopened": (WARNING, "finding", "layout inferred from the cyclic frames contradicted: re-opened"),
    "mcmb2.pn_malformed": (NOTE, "finding", "malformed to Wireshark's PROFINET dissector, decoded by the layout"),
    "mcmb2.time_backwards": (WARNING, "finding", "time went backwards (clock step): the rules restart there"),
    "mcmb2.cut": (NOTE, "finding", "frame cut by the capture (snaplen): only the bytes captured decoded"),
    "mcmb2.connect_cut": (NOTE, "finding", "Connect cut by the capture (snaplen): its layout not read"),
    "mcmb2.candidate": (WARNING, "candidate",
                        "look like an MC-MB2-PN or EC-Link device but were not recognised"),
    # EC-Link images (both transports)
    "eclink.relays_open": (WARNING, "relays", "ES-Link relays open"),
    "eclink.ru_stopped": (WARNING, "relays", "RU stopped"),
    "eclink.bu_state.unknown": (ERROR, "finding", "undefined BU state"),
    "eclink.vlaps.range": (ERROR, "finding", "VLAPs out of range"),
    "eclink.link_status.range": (ERROR, "finding", "undefined link status"),
    "eclink.ru_state.range": (ERROR, "finding", "undefined RU state"),
    "eclink.link_status.passive": (WARNING, "finding", "link status Passive where it is not allowed"),
    "eclink.ru_state.disarmed": (NOTE, "finding", "RU state Disarmed (used inside the BU only) on the wire"),
    "eclink.fields_disagree": (WARNING, "finding", "status fields contradict each other"),
    "eclink.link_status.fault": (WARNING, "finding", "a link reports a fault"),
    "eclink.percent.range": (ERROR, "finding", "percentage over 100"),
    "eclink.bool.range": (ERROR, "finding", "flag not 0 or 1"),
    "eclink.ru_disabled.range": (ERROR, "finding", "undefined RU disabled reason"),
    "eclink.joystick.range": (ERROR, "finding", "joystick out of range"),
    "eclink.unarmed_not_zero": (ERROR, "finding", "RU fields not 0 while no RU is armed"),
    "eclink.spare.not_zero": (WARNING, "finding", "spare not 0"),
    "eclink.periodic_size.range": (ERROR, "finding", "periodic data size over 51200"),
    "eclink.periodic_block.range": (ERROR, "finding", "periodic data block beyond the size"),
    "eclink.bad_length": (ERROR, "finding", "not an EC-Link image length"),
    # EC-Link over Modbus/TCP
    "eclink_modbus.no_request": (NOTE, "finding", "response without its request"),
    "eclink_modbus.mid_adu": (NOTE, "finding",
                              "TCP data from inside an ADU not decoded: segments out of order or not captured"),
    "eclink_modbus.poll_gap": (WARNING, "poll_gap", "input image not read"),
    "eclink_modbus.input_missing": (ERROR, "finding", "BU's input image no longer read (PCI timeout passed)"),
    "eclink_modbus.output_missing": (ERROR, "finding", "BU's output image no longer written (2000 ms passed)"),
    "eclink_modbus.connection_closed": (WARNING, "finding", "TCP connection to the BU closed (FIN)"),
    "eclink_modbus.connection_reset": (WARNING, "finding", "TCP connection to the BU reset (RST)"),
    "eclink_modbus.dropped": (NOTE, "finding", "images no longer valid: not taken for a BU any more"),
    "eclink_modbus.candidate": (WARNING, "candidate", "looks like an EC-Link BU but was not recognised"),
    # EC-Link over PROFINET
    "eclink_pnio.iops.bad": (WARNING, "finding", "IOPS not GOOD"),
    "eclink_pnio.short": (ERROR, "finding", "C-SDU shorter than the layout"),
    "eclink_pnio.layout.inferred": (NOTE, "finding", "layout inferred from the cyclic frames (no Connect)"),
    "eclink_pnio.layout.reopened": (WARNING, "finding",
                                    "layout inferred from the cyclic frames contradicted: re-opened"),
    "eclink_pnio.cut": (NOTE, "finding", "frame cut by the capture (snaplen): only the bytes captured decoded"),
    "eclink_pnio.pn_malformed": (NOTE, "finding",
                                 "malformed to Wireshark's PROFINET dissector, decoded by the layout"),
}

# What the EC-Link BU's display shows for a controller that lets PCO stand
# or does not echo a command from the RU with CAO (TS-0007 9), as the
# dissectors' messages end.
BAD_DATA = 'the BU shows "EC: Bad data"'

# The EC-Link handshake findings, the same on both transports.
HANDSHAKE = {
    "pci_stalled": (ERROR, "stall", "PCI"),
    "pco_stalled": (ERROR, "stall", "PCO"),
    "cmd_from_ru.late": (WARNING, "failed",
                         "command from RU{of} not echoed by CAO in time: the command failed, " + BAD_DATA),
    "cmd_to_ru.late": (WARNING, "failed",
                       "command to RU{of} not echoed by CAI in time: the command failed"),
    "cmd_from_ru.deadline": (NOTE, "deadline", "deadline of the command from RU{of} passed"),
    "cmd_to_ru.deadline": (NOTE, "deadline", "deadline of the command to RU{of} passed"),
    "cmd_from_ru.late_ack": (WARNING, "finding", "command from RU echoed by CAO late"),
    "cmd_to_ru.late_ack": (WARNING, "finding", "command to RU echoed by CAI late"),
    "bu_state_change": (NOTE, "state", "BU state changed"),
    "time_backwards": (WARNING, "finding", "time went backwards (clock step): the rules restart there"),
    "commands_mode": (NOTE, "finding", "Input + Commands mode (20-byte output image): PCO not supervised"),
}
for _transport in ("eclink_modbus", "eclink_pnio"):
    EXPERTS.update({_transport + "." + name: entry for name, entry in HANDSHAKE.items()})
# Modbus/TCP only: there the mode is guessed from the registers written
EXPERTS["eclink_modbus.pco_stalled.guessed"] = (
    WARNING, "finding", "PCO stalled where Input + Commands mode is only guessed: a fault in Standard mode")

# The dissector's severity of the findings the report rates higher (see above).
PROMOTED = {"eclink_modbus.candidate": NOTE, "mcmb2.candidate": NOTE}
# The string field beside each candidate note: the setting that decodes it.
CANDIDATE_SETTINGS = {"eclink_modbus.candidate": "eclink_modbus.candidate_setting",
                      "mcmb2.candidate": "mcmb2.candidate_setting"}


def severity_at_least(severity, threshold):
    return LEVELS[severity] >= LEVELS[threshold]


def label(name):
    """How a catalog entry reads in the timeline, without the parts it fills in."""
    severity, role, what = EXPERTS[name]
    what = what.format(of="")
    if role == "stall":
        return "%s stalled" % what
    if role == "gap":
        return "no %s (gap)" % what
    if role == "candidate":
        return "candidate that %s, with the setting that decodes it" % what
    return what


def markdown():
    """The severities table of docs/report.md (tests/test_report_catalog.py
    checks that the docs carry exactly this): a row per finding, errors first."""
    rows = {}
    for name, (severity, role, _) in EXPERTS.items():
        if role != "state":
            rows.setdefault((severity, label(name)), []).append(name)
    lines = ["| severity | finding | expert fields |", "|---|---|---|"]
    for severity in (ERROR, WARNING, NOTE):
        for (sev, text), names in rows.items():
            if sev == severity:
                lines.append("| %s | %s | %s |" % (severity, text, ", ".join("`%s`" % n for n in names)))
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(markdown(), end="")

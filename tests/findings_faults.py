"""Where each fault of the project's captures happened, by the schedule the
capture generator (tools/capgen/) follows, not by what the dissectors say:
{expert field: (capture, [frames that carry the fact])}.

The table of docs/findings.md "How findings read" names, per kind of finding, the
expert fields of each protocol; tests/test_findings_table.py checks that
each field sits on exactly these frames. Frame numbers count from 1; a
Modbus/TCP cycle of eclink_modbus.py is 4 frames (read query, response,
write query, response) after the 3-frame TCP handshake; a PROFINET capture
with its Connect starts with the 2 Connect frames.
"""

FAULTS = {
    # --- safety state the device reports
    # eglink_states.py: one VRPI per BU state, Initial, Stopped, External link
    # error, Blocked, Failed first (below 0x10: relays open)
    "eglink.bu_state.relays_open": ("eglink_states.pcap", [1, 2, 3, 4, 5]),
    # ... the VRPI whose RU state is Stopped
    "eglink.ru_state.stopped": ("eglink_states.pcap", [2]),
    # eclink_modbus_basic: the BU goes Blocked at the 12th cycle's response
    # and stays so in the next one
    "eclink.relays_open": ("eclink_modbus_basic.pcap", [45, 49]),
    # eclink_modbus_segments: the armed RU Stopped in the input images read
    "eclink.ru_stopped": ("eclink_modbus_segments.pcap", [10, 12, 16, 20]),
    # mcmb2_duplex_connect: uplink status Terminal absent (3), blocked (5),
    # active stop (11)
    "mcmb2.no_valid_data": ("mcmb2_duplex_connect.pcap", [3, 5, 11]),
    # --- E010 and the downlink watchdog
    "mcmb2.status.e010": ("mcmb2_duplex_connect.pcap", [13]),
    # mcmb2_duplex_watchdog: the downlink watchdog keeps 5 from frame 12 (t
    # 0.2 s); 2 s later (t 2.2 s) is frame 34
    "mcmb2.downlink_watchdog.stalled": ("mcmb2_duplex_watchdog.pcap", [34]),
    # mcmb2_simplex_unwritten: the downlink watchdog stays 0 from frame 4 (t
    # 0.101 s), the base reports Terminal present; past 2 s at frame 32 (2.201 s)
    "mcmb2.downlink_watchdog.unwritten": ("mcmb2_simplex_unwritten.pcap", [32]),
    # --- stalls: first frame past the limit that carries the counter
    # ... the uplink watchdog keeps 5 from frame 11 (t 0.2 s): past 1 s at 1.2 s
    "mcmb2.uplink_watchdog.stalled": ("mcmb2_duplex_watchdog.pcap", [23]),
    # --- streams that stop, the PROFINET cycle: mcmb2_duplex_stops, its
    # Connect (frames 1, 2; cycle 4 ms, data hold 40 ms), then a pair a 4 ms
    # tick i (uplink at 0.1 + 0.004 i, downlink 1 ms later) from frame 3;
    # uplink frames of ticks 10-12 lost: its tick 13 is frame 26; the
    # uplink ends after tick 29 (frame 58, t 0.216): past 40 ms is the
    # downlink of tick 39 (frame 69), past 1 s that of tick 279 (frame 309);
    # the downlink ends after tick 299 (frame 329, t 1.297), another
    # device's frames every 0.1 s from 1.35 s (frame 330) on: past 40 ms is
    # frame 330, past 2 s frame 350 (3.35 s)
    "mcmb2.frames_lost": ("mcmb2_duplex_stops.pcap", [26]),
    "mcmb2.data_hold_exceeded": ("mcmb2_duplex_stops.pcap", [69, 330]),
    "mcmb2.uplink_missing": ("mcmb2_duplex_stops.pcap", [309]),
    "mcmb2.downlink_missing": ("mcmb2_duplex_stops.pcap", [350]),
    # --- watchdog pace (SP-14-023 2.4, 3.1.2): mcmb2_duplex_watchdog, both
    # watchdogs keep 5 from t 1.0 s (frames 11, 12); 600 ms later, at t 1.6 s,
    # are frames 17 and 18
    "mcmb2.uplink_watchdog.slow": ("mcmb2_duplex_watchdog.pcap", [17]),
    "mcmb2.downlink_watchdog.slow": ("mcmb2_duplex_watchdog.pcap", [18]),
    # mcmb2_duplex_watchdog_steps: uplink 4 -> 7 (11), 9 -> 3 (17); downlink
    # 1 -> 0 (12), 1 -> 5 (16)
    "mcmb2.uplink_watchdog.jump": ("mcmb2_duplex_watchdog_steps.pcap", [11]),
    "mcmb2.uplink_watchdog.backwards": ("mcmb2_duplex_watchdog_steps.pcap", [17]),
    "mcmb2.downlink_watchdog.backwards": ("mcmb2_duplex_watchdog_steps.pcap", [12]),
    "mcmb2.downlink_watchdog.jump": ("mcmb2_duplex_watchdog_steps.pcap", [16]),
    # eclink_modbus_faults: PCI 2 read at 17 and again 700 ms later at 21
    "eclink_modbus.pci_stalled": ("eclink_modbus_faults.pcap", [21]),
    # ... PCO 4 written at 26, again 2.05 s later at 30
    "eclink_modbus.pco_stalled": ("eclink_modbus_faults.pcap", [30]),
    # eclink_pnio_connect: PCI kept from frame 23 for 625 ms; PCO from 38 for 2125 ms
    "eclink_pnio.pci_stalled": ("eclink_pnio_connect.pcap", [31]),
    "eclink_pnio.pco_stalled": ("eclink_pnio_connect.pcap", [72]),
    # --- Input + Commands mode (TS-0007 2.1, 8.4): the first output image of
    # the conversation (Modbus: the first write request of the recognised
    # connection, recognised at 13 by cycle 2's read response: cycle 2's write, 14)
    "eclink_modbus.commands_mode": ("eclink_modbus_commands.pcap", [14]),
    # PCO 0 since frame 6 (0.1 s), past 2000 ms at frame 74 (2.235 s), an output write
    "eclink_modbus.pco_stalled.guessed": ("eclink_modbus_commands.pcap", [74]),
    "eclink_pnio.commands_mode": ("eclink_pnio_commands.pcap", [4]),
    # --- EG-Link periodic gaps (eglink_analysis.py)
    # vrpi_gap: VRPI every 125 ms, none from frame 10 (t 0.5 s) to frame 20
    # (t 1.375 s); the first BU packet past 500 ms is the VRPO at 16
    "eglink.analysis.vrpi_missing": ("eglink_analysis_vrpi_gap.pcap", [16]),
    "eglink.analysis.vrpi_gap": ("eglink_analysis_vrpi_gap.pcap", [20]),
    # vrpo_gap: no VRPO from frame 18 for 2.6 s; the VRPI at 35 is the first
    # packet past 2 s, the VRPO at 40 ends it
    "eglink.analysis.vrpo_missing": ("eglink_analysis_vrpo_gap.pcap", [35]),
    "eglink.analysis.vrpo_gap": ("eglink_analysis_vrpo_gap.pcap", [40]),
    # --- poll gap: the input image not read from frame 16 (t 0.475) to 20
    # (t 1.175: 700 ms), and from 24 (t 1.3) to 28 (t 3.35: 2.05 s)
    "eclink_modbus.poll_gap": ("eclink_modbus_faults.pcap", [20, 28]),
    # --- images that stop, connections that end (eclink_modbus_stops, a tick
    # every 125 ms: BU 1 at t, BU 2 at t + 30 ms, an ordinary server at t + 90
    # ms): BU 1's input image last read at 0.725 s (60), its deadline 1.225 s,
    # the first frame after it BU 1's write at 1.235 s (94); its output image
    # last written at 1.485 s (110), the first frame after 3.485 s BU 2's read
    # at 3.505 s (211)
    "eclink_modbus.input_missing": ("eclink_modbus_stops.pcap", [94]),
    "eclink_modbus.output_missing": ("eclink_modbus_stops.pcap", [211]),
    # ... BU 1's connection closed by the controller's FIN at 1.695 s (124),
    # the next frame with a payload BU 2's read at 1.755 s (127); BU 2 resets
    # its connection at 4.695 s (271), the controller's new connection reads at
    # 4.755 s (275)
    "eclink_modbus.connection_closed": ("eclink_modbus_stops.pcap", [127]),
    "eclink_modbus.connection_reset": ("eclink_modbus_stops.pcap", [275]),
    # --- undefined states and statuses (eglink_range: one VRPI per breach)
    # BU state 0x05 (8: also below 0x10) and 0x20 (9)
    "eglink.bu_state.unknown": ("eglink_range.pcap", [8, 9]),
    "eglink.ru_state.unknown": ("eglink_range.pcap", [11]),
    "eglink.link_status.unknown": ("eglink_range.pcap", [10]),
    "eglink.ru_disabled.unknown": ("eglink_range.pcap", [4]),
    # eclink_modbus_faults: the image of frame 37 (RU state 5, EG-Link status
    # 7, ...) and of 39 (BU state 0x42)
    "eclink.bu_state.unknown": ("eclink_modbus_faults.pcap", [39]),
    "eclink.ru_state.range": ("eclink_modbus_faults.pcap", [37]),
    "eclink.link_status.range": ("eclink_modbus_faults.pcap", [37]),
    # mcmb2_duplex_connect: status 0x3 from frame 17 on, every uplink frame
    "mcmb2.status.undefined": ("mcmb2_duplex_connect.pcap", [17, 19, 21, 23, 25, 27, 29, 31, 33, 35, 37]),
    # --- out-of-range values
    "eglink.joystick.range": ("eglink_range.pcap", [1]),
    "eglink.ru_battery.range": ("eglink_range.pcap", [2]),
    "eglink.vlaps.range": ("eglink_range.pcap", [3]),
    "eglink.flag.invalid": ("eglink_range.pcap", [5]),
    "eglink.armed_ru.unarmed_data": ("eglink_range.pcap", [6, 12]),
    "eclink.joystick.range": ("eclink_modbus_faults.pcap", [37]),
    "eclink.percent.range": ("eclink_modbus_faults.pcap", [37]),
    "eclink.vlaps.range": ("eclink_modbus_faults.pcap", [37]),
    "eclink.unarmed_not_zero": ("eclink_modbus_faults.pcap", [39]),
    "eclink.periodic_size.range": ("eclink_modbus_faults.pcap", [40]),
    # eclink_modbus_link_states: C-Link Passive with RU 0x1234 armed (17),
    # EG-Link Passive (25); RU state 1 (21); the disarmed BU's C-Link
    # Passive (29) is allowed
    "eclink.link_status.passive": ("eclink_modbus_link_states.pcap", [17, 25]),
    "eclink.ru_state.disarmed": ("eclink_modbus_link_states.pcap", [21]),
    # ... EC-Link Data error while the BU stays Armed (33: the fault, and the
    # contradiction TS-0007 9 makes of it); RU Enabled while tilted (37)
    "eclink.link_status.fault": ("eclink_modbus_link_states.pcap", [33]),
    "eclink.fields_disagree": ("eclink_modbus_link_states.pcap", [33, 37]),
    # mcmb2_polled_connect: the uplink of frame 15 says Y=20, the Connect 24
    "mcmb2.layout_mismatch": ("mcmb2_polled_connect.pcap", [15]),
    # --- checksum and size (eglink.py)
    "eglink.crc.bad": ("eglink_bad_crc.pcap", [1, 2, 3, 4, 5, 6]),
    "eglink.size.invalid": ("eglink_wrong_size.pcap", [2, 3, 4, 5, 6, 7, 8, 9]),
    "eglink.too_short": ("eglink_wrong_size.pcap", [10, 11, 12]),
    # --- contract deviations
    "eglink.payload_spare.nonzero": ("eglink_range.pcap", [7]),
    "eclink.spare.not_zero": ("eclink_modbus_faults.pcap", [37, 40]),
    "mcmb2.iops.bad": ("mcmb2_duplex_connect.pcap", [9]),
    "mcmb2.iocs.bad": ("mcmb2_duplex_connect.pcap", [16]),
    "mcmb2.reserved.not_zero": ("mcmb2_polled_connect.pcap", [18]),
    # --- lost and repeated (eglink_analysis.py): serials skip before 13 and 15;
    # frames 9 and 15 repeat earlier serials
    "eglink.analysis.serial_gap": ("eglink_analysis_lost.pcap", [13, 15]),
    "eglink.analysis.serial_repeat": ("eglink_analysis_repeated.pcap", [9, 15]),
    # --- commands not acknowledged in time: the command's own frame
    # vrci_unacked: VRCI Cmd=8 first sent in frame 5, never acknowledged
    "eglink.analysis.vrci_unacked": ("eglink_analysis_vrci_unacked.pcap", [5]),
    # vrco_unacked: VRCO 4 (frame 5) never acknowledged, VRCO 5 (frame 52)
    # acknowledged 2.3 s later (frame 94)
    "eglink.analysis.vrco_unacked": ("eglink_analysis_vrco_unacked.pcap", [5, 67]),
    "eglink.analysis.late_ack": ("eglink_analysis_vrco_unacked.pcap", [128]),
    # eclink_modbus_faults: CCI 2 read in frame 17 and CCO 2 written in 18,
    # neither echoed within 2 s; CAO echoes CCI 2 in frame 34 (3.0 s)
    "eclink_modbus.cmd_from_ru.late": ("eclink_modbus_faults.pcap", [17]),
    "eclink_modbus.cmd_to_ru.late": ("eclink_modbus_faults.pcap", [18]),
    "eclink_modbus.cmd_from_ru.late_ack": ("eclink_modbus_faults.pcap", [34]),
    # eclink_pnio_connect: CCI 2 from the input frame 43, never echoed
    "eclink_pnio.cmd_from_ru.late": ("eclink_pnio_connect.pcap", [43]),
    # --- the first frame after a missed deadline (the notes naming the command)
    "eglink.analysis.vrci_deadline": ("eglink_analysis_vrci_unacked.pcap", [61]),
    "eglink.analysis.vrco_deadline": ("eglink_analysis_vrco_unacked.pcap", [61, 123]),
    # the read query of the cycle 2.6 s after the commands
    "eclink_modbus.cmd_from_ru.deadline": ("eclink_modbus_faults.pcap", [28]),
    "eclink_modbus.cmd_to_ru.deadline": ("eclink_modbus_faults.pcap", [28]),
    "eclink_pnio.cmd_from_ru.deadline": ("eclink_pnio_connect.pcap", [76]),
    # --- shared group: the first packet of each BU and controller once two share it
    "eglink.analysis.shared_group": ("eglink_analysis_shared_group.pcap", [2, 3, 4, 5]),
    # wrong_port: the controller's VRAO to port 6001 (8), its VRCO to the input port (14)
    "eglink.analysis.wrong_port": ("eglink_analysis_wrong_port.pcap", [8, 14]),
    # clock_step: the first packet after the clock was set back 2 s
    "eglink.analysis.time_backwards": ("eglink_analysis_clock_step.pcap", [27]),
    # --- the TS-0006 rules of eglink_analysis_spec_rules (tools/capgen/eglink_analysis.py
    # spec_rules): BU 0x1002's VRPO bursts from 0: packet 1 of the 4th 15 ms late (20), the
    # 6th's packet 0 short (its packet 1, 32), the 9th 250 ms after the 8th (46), the 11th
    # numbered 0, 2 (65); BU 0x1001: VRCI 1 resent 50 ms after its resend (24), VRCI 2 (frame
    # 38) not resent by the VRPO at 0.84 s (42), VRCI 3 resent after its VRAO (56), VRCO 3
    # after VRCO 1 (69), VRCI 4 (frame 80) resent 2.1 s after it (197)
    "eglink.analysis.burst_spread": ("eglink_analysis_spec_rules.pcap", [20]),
    "eglink.analysis.vrpo_not_full": ("eglink_analysis_spec_rules.pcap", [32]),
    "eglink.analysis.vrpo_interval": ("eglink_analysis_spec_rules.pcap", [46]),
    "eglink.analysis.vrpo_number": ("eglink_analysis_spec_rules.pcap", [65]),
    "eglink.analysis.resend_interval": ("eglink_analysis_spec_rules.pcap", [24]),
    "eglink.analysis.not_resent": ("eglink_analysis_spec_rules.pcap", [42]),
    "eglink.analysis.resent_after_ack": ("eglink_analysis_spec_rules.pcap", [56]),
    "eglink.analysis.command_id_sequence": ("eglink_analysis_spec_rules.pcap", [69]),
    "eglink.analysis.resent_after_deadline": ("eglink_analysis_spec_rules.pcap", [197]),
    # eglink_header: the VRPI of revision 1 (frame 1)
    "eglink.analysis.revision_ignored": ("eglink_header.pcap", [1]),
    # eglink_states: a VRPI with RU state 1 (8), one with EG-Link status Passive (13)
    "eglink.ru_state.disarmed": ("eglink_states.pcap", [8]),
    "eglink.link_status.passive": ("eglink_states.pcap", [13]),
    # ... links No link (1: EG-Link, C-Link), Link error, Interface error, Data
    # error (3); RU 0xbeef armed with RU state Initial (7)
    "eglink.link_status.fault": ("eglink_states.pcap", [1, 3]),
    "eglink.fields_disagree": ("eglink_states.pcap", [7]),
    # corrupted: serial 103 with a bad CRC (8) before the VRPI at 10, the VRPO
    # with a wrong Size (13) before the VRPO at 14
    "eglink.analysis.serial_corrupted": ("eglink_analysis_corrupted.pcap", [10, 14]),
    # eglink_truncated: every packet cut by the snap length
    "eglink.cut": ("eglink_truncated.pcap", [1, 2, 3, 4, 5, 6]),
    # --- state changes, retransmissions, inferred layouts
    # session: Initial -> Disarmed (10) -> Armed (19) -> Stopped (41) -> Armed (52)
    "eglink.analysis.bu_state_changed": ("eglink_analysis_session.pcap", [10, 19, 41, 52]),
    "eglink.analysis.retransmission": ("eglink_analysis_vrci_retransmission.pcap", [10, 13]),
    "eclink_modbus.bu_state_change": ("eclink_modbus_basic.pcap", [45]),
    "eclink_pnio.bu_state_change": ("eclink_pnio_connect.pcap", [7]),
    "eclink_pnio.layout.inferred": ("eclink_pnio_noconnect.pcap", [6]),
    "mcmb2.layout.inferred": ("mcmb2_duplex_noconnect.pcap", [6]),
    # mcmb2_duplex_reopen_noconnect: inferred in frame 6, the DAP's IOPS 0x81
    # in frame 9 (the fifth uplink frame) re-opens it
    "mcmb2.layout.reopened": ("mcmb2_duplex_reopen_noconnect.pcap", [9]),
    # --- looks like ours, not recognised: mcmb2_duplex_e010_noconnect, a
    # base in E010 whose downlink watchdog never moves, without a Connect:
    # never settled, every frame of both directions (second pass)
    "mcmb2.candidate": ("mcmb2_duplex_e010_noconnect.pcap", list(range(1, 11))),
    # --- commands and acknowledgements in time
    "eglink.analysis.command": ("eglink_analysis_vrci_retransmission.pcap", [7]),
    "eglink.analysis.ack": ("eglink_analysis_vrci_retransmission.pcap", [14]),
    "eclink_modbus.cmd_from_ru": ("eclink_modbus_basic.pcap", [17]),
    "eclink_pnio.cmd_from_ru": ("eclink_pnio_connect.pcap", [9, 43]),
    "eclink_modbus.cmd_to_ru.ack": ("eclink_modbus_basic.pcap", [37]),
    "eclink_pnio.cmd_to_ru.ack": ("eclink_pnio_connect.pcap", [21]),
    # --- recognition: eclink_modbus_excerpt, a BU too short for the evidence
    # (never accepted): its two input images (2, 10) and its write (5) have
    # a BU's shape; the IO device beside it (0/1 inputs, counting writes) none
    "eclink_modbus.candidate": ("eclink_modbus_excerpt.pcap", [2, 5, 10]),
    # --- the capture's time steps back 2 s (tools/capgen/clock_step.py): on
    # the first frame of the conversation after the step
    "eclink_modbus.time_backwards": ("clockstep_modbus.pcap", [24]),
    "eclink_pnio.time_backwards": ("clockstep_eclink_pnio.pcap", [50]),
    "mcmb2.time_backwards": ("clockstep_mcmb2.pcap", [20]),
    # --- frames the capture cut (tools/capgen/snaplen.py): on each cut frame
    # decoded by a known layout, and on the cut Connect request and response
    "mcmb2.cut": ("snaplen_mcmb2.pcap", list(range(11, 31))),
    "eclink_pnio.cut": ("snaplen_eclink_pnio.pcap", list(range(31, 61))),
    "mcmb2.connect_cut": ("snaplen_connect.pcap", [1, 2]),
}

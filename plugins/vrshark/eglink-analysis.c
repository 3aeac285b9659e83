/* eglink-analysis.c
 * EG-Link conversation analysis (twin: lua/vrshark/eglink_analysis.luam):
 * the walk of one packet through the files that track it (eglink-shared.h
 * lists them), its preferences, the init routine and the "eglink" tap.
 *
 * Everything is computed on the first pass, in frame order, and stored per
 * frame in file scope, so a single pass, "tshark -2" and clicking around in
 * the GUI show the same findings (only a failed command's is placed
 * differently, below). Most frames need only a 16-byte record in a
 * table indexed by frame number; a frame with findings, a command link or a
 * reassembly ID keeps its full record with p_add_proto_data. A finding that depends
 * on time passing (a missing VRPI/VRPO) is reported on the first packet of
 * the BU that arrives after the deadline: that is the earliest packet at
 * which a one-pass reader knows it. An unacknowledged command is reported
 * on the command itself, with a forward link to that packet (second pass and
 * GUI); the packet gets a note naming the command. In one pass the command
 * is behind the reader already, so that packet carries the command's
 * warning instead (eglink-findings.c:show_failed()).
 *
 * Which packets belong to one BU: the BU sends VRPI/VRCI/VRAI to its input
 * port, the machine controller sends VRPO/VRCO/VRAO to the input port + 2,
 * both usually to the same multicast group. Packets meet on a channel:
 *   (multicast group, input port)                      for multicast, or
 *   (the two unicast addresses, unordered, input port)  for unicast,
 * where the input port is the destination port of a BU packet and the
 * destination port - 2 of a controller packet. Every BU ships with the same
 * group and ports, so one channel may carry several BUs: on it, a BU is
 * its origin and source address, a controller its source address (its
 * packets carry origin 0). Each sender has its own serials, periodic
 * interval and commands. A controller is joined to its BU by the command
 * IDs acknowledged between them (a VRAO for a BU's VRCI, a VRAI for the
 * controller's VRCO), or while it is the only one beside the only BU of the
 * channel; until then its packets are analysed on their own.
 *
 * analyse_packet() reads as the steps every packet takes, the ones of a
 * healthy BU's VRPI or VRPO cheap; what is rare (a bad CRC, a wrong port,
 * an origin change, a restart, an orphan controller, the findings' text)
 * is in the functions those steps branch to, in the files eglink-shared.h
 * lists.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-shared.h"

#include "eglink-compat.h"

#include <epan/tap.h>

/* p_add_proto_data key: one record per EG-Link layer of a frame. */
#define EGLINK_ANALYSIS_KEY_BASE 0x45410000u

static int eglink_tap = -1;

/* Preferences */
guint eglink_pref_vrpi_gap_ms = 500;
guint eglink_pref_vrpo_gap_ms = 2000;
guint eglink_pref_vrci_ack_timeout_ms = 2000;
guint eglink_pref_vrco_ack_timeout_ms = 2000;
guint eglink_pref_periodic_size = 0;
eglink_pref_bool_t eglink_pref_reassemble = TRUE;
guint eglink_pref_resend_tolerance_ms = 20;
guint eglink_pref_burst_spread_ms = 10;

static void
eglink_analysis_init(void)
{
    eglink_records_init();
    eglink_channels_init();
    eglink_timing_init();
    eglink_bursts_init();
}

/* The sender of a packet, found on the channel it belongs to. */
typedef struct {
    gboolean input;             /* a BU packet (VRPI, VRCI, VRAI) */
    eglink_chan_t *chan;
    eglink_bu_t *bu;            /* a BU packet's BU */
    eglink_ctrl_t *ctrl;        /* a controller packet's controller */
    eglink_sender_t *s;         /* ... either's serials, intervals and commands */
    guint32 expected_port;      /* the port it belongs on when it went to another, else 0 */
} eglink_sender_ref_t;

/* The packet's channel and sender, and the BU the record names. */
static void
find_sender(packet_info *pinfo, const eglink_info_t *info, eglink_frame_t *fd, eglink_sender_ref_t *p)
{
    p->input = eglink_is_input(info->type);
    p->expected_port = 0;
    p->chan = p->input ? eglink_bu_chan(pinfo, &p->expected_port)
                       : eglink_ctrl_chan(pinfo, &p->expected_port);
    p->bu = NULL;
    p->ctrl = NULL;
    check_clock(pinfo, fd);
    if (p->input) {
        p->bu = eglink_bu_lookup(pinfo, p->chan, info->origin);
        p->s = &p->bu->s;
    } else {
        p->ctrl = eglink_ctrl_lookup(pinfo, p->chan);
        p->s = &p->ctrl->s;
    }
    join_if_alone(p->chan, fd, pinfo);
    if (p->ctrl && p->ctrl->n_orphan_acks && p->chan->n_bus)
        match_orphan_acks(p->ctrl);
    fd->bu = p->input ? p->bu : p->ctrl->bu;
    fd->ctrl = p->input || p->ctrl->joined_by_ack ? NULL : p->ctrl;
    if (fd->bu) {
        fd->flags |= FF_ORIGIN;
        fd->bu_origin = fd->bu->origin;
    }
}

/* The origin of a BU packet: the BU's own, once known from a valid packet. */
static void
track_origin(eglink_bu_t *bu, eglink_frame_t *fd, const eglink_info_t *info)
{
    if (!bu->origin_known) {
        /* Known so far only from packets that failed their check: no origin
         * change (the BU keeps its name, so that every pass names it alike). */
        bu->origin = info->origin;
        fd->bu_origin = bu->origin;
    } else if (bu->origin != info->origin) {
        /* Another device at the BU's address: it counts its own serials. */
        add_finding(fd, FND_ORIGIN, 0, bu->origin, 0);
        bu->origin = info->origin;
        bu->s.have_serial = FALSE;
        fd->bu_origin = bu->origin;
    }
    bu->origin_known = TRUE;
}

/* An acknowledgement may tell which BU a controller talks to. */
static void
join_by_ack(const eglink_sender_ref_t *p, eglink_frame_t *fd, const eglink_info_t *info)
{
    eglink_ctrl_t *ctrl = p->ctrl;

    if (info->type == EGLINK_TYPE_VRAO && info->has_command_id) {
        fd->cmd = vrci_acknowledged(ctrl, info->command_id);
        if (waits_for_ack(fd->cmd))
            ctrl->joined_by_ack = TRUE;     /* (evidence now, not only being alone) */
    } else if (info->type == EGLINK_TYPE_VRAI && info->has_command_id) {
        fd->cmd = vrco_acknowledged(p->bu, info->command_id);
    }
    if (ctrl && ctrl->joined_by_ack && (fd->ctrl || ctrl->bu != fd->bu)) {
        fd->bu = ctrl->bu;
        fd->ctrl = NULL;
        fd->flags |= FF_ORIGIN;
        fd->bu_origin = fd->bu->origin;
    }
}

/* What the packet's type adds: its interval, burst, command or acknowledgement. */
static void
track_type(const eglink_sender_ref_t *p, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info)
{
    switch (info->type) {
    case EGLINK_TYPE_VRPI:
        track_vrpi(p->bu, fd, pinfo, info);
        break;
    case EGLINK_TYPE_VRPO:
        track_interval(p->s, fd, pinfo, eglink_pref_vrpo_gap_ms, FND_VRPO_GAP);
        if (info->has_packet_number)
            track_burst(&p->ctrl->burst, fd, pinfo, info);
        break;
    case EGLINK_TYPE_VRCI:
    case EGLINK_TYPE_VRCO:
        if (info->has_command_id)
            track_command(p->s, fd, pinfo, p->input ? EGLINK_DIR_IN : EGLINK_DIR_OUT, info->command_id);
        break;
    case EGLINK_TYPE_VRAO:      /* acknowledges a VRCI */
    case EGLINK_TYPE_VRAI:      /* acknowledges a VRCO */
        if (info->has_command_id) {
            eglink_cmd_t *cmd = fd->cmd;
            fd->cmd = NULL;
            track_ack(cmd, fd, pinfo, p->input ? EGLINK_DIR_OUT : EGLINK_DIR_IN, info->command_id);
            if (!cmd && !p->input && p->chan->own_port && !p->chan->n_bus)
                remember_orphan_ack(p->ctrl, pinfo, info->command_id);
        }
        break;
    default:
        break;
    }
}

/* The first pass over a packet: its sender, serial, deadlines and what its
 * type tracks, written into its record. */
static void
analyse_packet(packet_info *pinfo, const eglink_info_t *info, eglink_frame_t *fd)
{
    eglink_sender_ref_t p;

    find_sender(pinfo, info, fd, &p);
    /* Receivers silently drop illegal packets (TS-0006 5.1.5); so does the
     * analysis, but for their serial: a gap it fills is no loss. */
    if (!info->crc_ok || !info->size_ok) {
        fd->flags |= FF_INVALID;
        remember_corrupted(p.s, pinfo, info);
        return;
    }
    if (p.expected_port)
        add_finding(fd, FND_WRONG_PORT, 0, p.expected_port, 0);
    if (info->revision != 0) {
        track_revision(p.s, fd, pinfo, info);
        return;
    }
    if (p.input)
        track_origin(p.bu, fd, info);
    track_serial(p.s, fd, pinfo, info, p.input);
    if (fd->serial_status == SERIAL_REPEAT)
        return;
    if (fd->serial_status == SERIAL_RESTART || fd->serial_status == SERIAL_FIRST)
        p.s->have_cmd_id = FALSE;   /* a sender (re)starting numbers its commands afresh */
    join_by_ack(&p, fd, info);
    check_shared(p.chan, p.s, fd);
    check_deadlines(p.chan, fd->bu, p.ctrl, fd, pinfo, info);
    track_type(&p, fd, pinfo, info);
}

static void
queue_tap(packet_info *pinfo, const eglink_info_t *info, const eglink_frame_t *fd)
{
    eglink_tap_info_t *t = wmem_new0(pinfo->pool, eglink_tap_info_t);
    const eglink_finding_t *f;

    t->bu_name = fd->bu ? fd->bu->name : fd->ctrl->name;
    t->is_bu = fd->bu != NULL;
    t->type = info->type;
    t->invalid = (fd->flags & FF_INVALID) != 0;
    t->repeated = fd->serial_status == SERIAL_REPEAT;
    t->lost = serial_lost(fd, info->serial);
    if ((fd->flags & FF_DELTA) && (info->type == EGLINK_TYPE_VRPI || info->type == EGLINK_TYPE_VRPO)) {
        t->has_interval = TRUE;
        t->interval_ns = fd->delta_ns;
    }
    if (fd->cmd && (info->type == EGLINK_TYPE_VRCI || info->type == EGLINK_TYPE_VRCO)) {
        t->retransmission = (fd->flags & FF_RETRANS) != 0;
        t->new_command = !t->retransmission;
    }
    if (fd->flags & FF_FIRST_ACK) {
        t->first_ack = TRUE;
        t->ack_ns = fd->delta_ns;
    }
    if (fd->flags & FF_BURST_LAST)
        t->burst_complete = TRUE;
    for (f = fd->findings; f; f = f->next) {
        if (f->kind == FND_FAILED_VRCI)
            t->failed[EGLINK_DIR_IN]++;
        else if (f->kind == FND_FAILED_VRCO)
            t->failed[EGLINK_DIR_OUT]++;
        /* A late acknowledgement that is itself the first packet past the
         * deadline: the command failed here too. */
        else if (f->kind == FND_LATE_ACK && fd->cmd && fd->cmd->deadline_frame == pinfo->num)
            t->failed[fd->cmd->dir]++;
        else if (f->kind == FND_BURST_DONE)
            t->burst_complete = TRUE;
        else if (f->kind == FND_BU_STATE && f->ns >= 0) {
            t->has_state_period = TRUE;
            t->prev_state = (guint8)f->value;
            t->state_ns = f->ns;
        }
        else if (f->kind == FND_BURST_INCOMPLETE)
            t->burst_incomplete = TRUE;
    }
    tap_queue_packet(eglink_tap, pinfo, t);
}

void
eglink_analysis_dissect(tvbuff_t *tvb, packet_info *pinfo, proto_tree *eglink_tree,
                        proto_item *eglink_item _U_, const eglink_info_t *info)
{
    guint32 key = EGLINK_ANALYSIS_KEY_BASE + pinfo->curr_layer_num;
    const eglink_frame_t *fd;
    eglink_frame_t buf, view, *stored;

    /* Unknown types are not part of the packet flow; a copy quoted in an
     * ICMP error is not a packet of the conversation. */
    if (info->type == EGLINK_TYPE_UNKNOWN || pinfo->flags.in_error_pkt)
        return;

    if (!PINFO_FD_VISITED(pinfo))
        eglink_frame_renumbered(pinfo);
    fd = eglink_frame_fetch(pinfo, key, info->serial, &buf);
    if (!fd) {
        if (PINFO_FD_VISITED(pinfo))
            return;
        memset(&buf, 0, sizeof(buf));
        eglink_orphan_pending = NULL;
        analyse_packet(pinfo, info, &buf);
        stored = eglink_frame_store(pinfo, key, info->serial, &buf);
        if (eglink_orphan_pending)
            eglink_orphan_pending->fd = stored;
        fd = &buf;
    }
    fd = frame_view(fd, &view);
    show_frame(tvb, pinfo, eglink_tree, info, fd);
    queue_tap(pinfo, info, fd);
}

/* ---------------------------------------------------------------------- */

void
eglink_analysis_register(int proto, module_t *prefs)
{
    eglink_records_register(proto);
    eglink_findings_register(proto);
    eglink_bursts_register(proto);

    prefs_register_uint_preference(prefs, "vrpi_gap_ms", "VRPI gap threshold (ms)",
        "A VRPI later than this after the previous one of its BU is flagged; the machine "
        "controller should flag an error after e.g. 500 ms (the BU sends every 125 ms)",
        10, &eglink_pref_vrpi_gap_ms);
    prefs_register_uint_preference(prefs, "vrpo_gap_ms", "VRPO gap threshold (ms)",
        "A VRPO later than this after the previous one to its BU is flagged; the BU flags an "
        "error after 2000 ms and, with an RU armed, opens the ES-Link relays",
        10, &eglink_pref_vrpo_gap_ms);
    prefs_register_uint_preference(prefs, "vrci_ack_timeout_ms", "VRCI acknowledgement timeout (ms)",
        "A VRCI not acknowledged by a VRAO within this time failed (the BU gives up after 2000 ms)",
        10, &eglink_pref_vrci_ack_timeout_ms);
    prefs_register_uint_preference(prefs, "vrco_ack_timeout_ms", "VRCO acknowledgement timeout (ms)",
        "A VRCO not acknowledged by a VRAI within this time is flagged",
        10, &eglink_pref_vrco_ack_timeout_ms);
    prefs_register_uint_preference(prefs, "periodic_size", "Periodic data size (bytes, 0 = unknown)",
        "Configured size of the VRPO periodic data; a split burst ends when it reaches this size. "
        "0: a burst ends with a packet shorter than 488 bytes or when the next burst starts",
        10, &eglink_pref_periodic_size);
    prefs_register_uint_preference(prefs, "resend_tolerance_ms", "Command resend tolerance (ms)",
        "A VRCI or VRCO is resent every 100 ms until acknowledged (TS-0006 5.1.3, 5.1.4): a resend "
        "further than this from 100 ms after the previous transmission is noted, and an "
        "unacknowledged command not resent within 100 ms + this is flagged",
        10, &eglink_pref_resend_tolerance_ms);
    prefs_register_uint_preference(prefs, "burst_spread_ms", "VRPO burst spread limit (ms)",
        "The packets of a split VRPO are sent without delay (TS-0006 5.1.2): a packet of a burst "
        "later than this after the one before it is noted",
        10, &eglink_pref_burst_spread_ms);
    prefs_register_bool_preference(prefs, "reassemble_vrpo", "Reassemble split VRPO bursts",
        "Reassemble the periodic data of VRPO bursts split into several packets",
        &eglink_pref_reassemble);

    eglink_channels_register();
    register_init_routine(eglink_analysis_init);
    eglink_tap = register_tap("eglink");
    eglink_stats_register();
}

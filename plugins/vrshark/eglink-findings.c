/* eglink-findings.c
 * What a frame's record says, on every pass (twin: lua/vrshark/eglink_findings.luam):
 * the "eglink.analysis" tree, the expert info of each finding and the tags
 * it adds to the Info column. Registers the analysis fields and expert infos.
 *
 * The warning of an unacknowledged command sits on the command itself, with
 * a forward link to the packet at which its deadline was seen passing
 * (second pass and GUI); that packet gets a note naming the command. In
 * one pass the command is behind the reader already, so that packet carries
 * the command's warning instead (show_failed()).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-shared.h"

#include "eglink-compat.h"

#include <epan/expert.h>
#include <epan/to_str.h>

static int hf_analysis = -1;
static int hf_bu_stream = -1;
static int hf_bu_origin = -1;
static int hf_device = -1;
static int hf_joined_alone = -1;
static int hf_expected_serial = -1;
static int hf_lost = -1;
static int hf_repeat_of = -1;
static int hf_time_since_prev_vrpi = -1;
static int hf_time_since_prev_vrpo = -1;
static int hf_retransmission_of = -1;
static int hf_ack_in = -1;
static int hf_ack_to = -1;
static int hf_ack_time = -1;
static int hf_failed_command = -1;
static int hf_deadline_in = -1;
static int hf_incomplete_burst = -1;
static int hf_last_vrpi = -1;
static int hf_last_vrpo = -1;
static int hf_corrupted_in = -1;
static int hf_expected_port = -1;
static int hf_time_backwards_after = -1;

static gint ett_analysis = -1;

static expert_field ei_serial_gap = EI_INIT;
static expert_field ei_serial_repeat = EI_INIT;
static expert_field ei_serial_restart = EI_INIT;
static expert_field ei_vrpi_gap = EI_INIT;
static expert_field ei_vrpo_gap = EI_INIT;
static expert_field ei_vrpi_missing = EI_INIT;
static expert_field ei_vrpo_missing = EI_INIT;
static expert_field ei_retransmission = EI_INIT;
static expert_field ei_vrci_unacked = EI_INIT;
static expert_field ei_vrco_unacked = EI_INIT;
static expert_field ei_vrci_deadline = EI_INIT;
static expert_field ei_vrco_deadline = EI_INIT;
static expert_field ei_late_ack = EI_INIT;
static expert_field ei_unknown_ack = EI_INIT;
static expert_field ei_bu_state_changed = EI_INIT;
static expert_field ei_origin_changed = EI_INIT;
static expert_field ei_burst_incomplete = EI_INIT;
static expert_field ei_burst_size = EI_INIT;
static expert_field ei_shared_group = EI_INIT;
static expert_field ei_command = EI_INIT;
static expert_field ei_ack = EI_INIT;
static expert_field ei_serial_corrupted = EI_INIT;
static expert_field ei_wrong_port = EI_INIT;
static expert_field ei_time_backwards = EI_INIT;
static expert_field ei_vrpo_number = EI_INIT;
static expert_field ei_vrpo_interval = EI_INIT;
static expert_field ei_burst_spread = EI_INIT;
static expert_field ei_vrpo_not_full = EI_INIT;
static expert_field ei_resend_interval = EI_INIT;
static expert_field ei_not_resent = EI_INIT;
static expert_field ei_resent_after_ack = EI_INIT;
static expert_field ei_resent_after_deadline = EI_INIT;
static expert_field ei_command_id_sequence = EI_INIT;
static expert_field ei_revision_ignored = EI_INIT;
static expert_field ei_not_joined = EI_INIT;
static expert_field ei_join_withdrawn = EI_INIT;

static nstime_t
ns_to_nstime(gint64 ns)
{
    nstime_t t;

    t.secs = (time_t)(ns / 1000000000);
    t.nsecs = (int)(ns % 1000000000);
    return t;
}

/* "0.812 s": rounded to the millisecond */
static const char *
ns_str(wmem_allocator_t *scope, gint64 ns)
{
    gint64 ms = (ns + 500000) / 1000000;     /* rounded to the millisecond */

    return wmem_strdup_printf(scope, "%" G_GINT64_FORMAT ".%03d s", ms / 1000, (int)(ms % 1000));
}

/* A time a finding compares with a limit (in ms): rounded to the
 * millisecond, or with as many more digits as it takes not to read as the
 * limit itself, which it is not ("0.2003 s" for a VRPO interval outside 50
 * to 200 ms). Rounding never carries a time across its limit, which has
 * no more digits. */
static const char *
ns_str_past(wmem_allocator_t *scope, gint64 ns, guint limit_ms)
{
    gint64 unit = 1000000, per_s = 1000, v = (ns + unit / 2) / unit;
    int digits = 3;

    while (unit > 1 && v * unit == ms_to_ns(limit_ms)) {
        unit /= 10;
        per_s *= 10;
        digits++;
        v = (ns + unit / 2) / unit;
    }
    return wmem_strdup_printf(scope, "%" G_GINT64_FORMAT ".%0*" G_GINT64_FORMAT " s",
                              v / per_s, digits, v % per_s);
}

static proto_item *
add_generated_uint(proto_tree *tree, int hf, tvbuff_t *tvb, guint32 value)
{
    proto_item *ti = proto_tree_add_uint(tree, hf, tvb, 0, 0, value);

    proto_item_set_generated(ti);
    return ti;
}

static proto_item *
add_generated_time(proto_tree *tree, int hf, tvbuff_t *tvb, gint64 ns)
{
    nstime_t t = ns_to_nstime(ns);
    proto_item *ti = proto_tree_add_time(tree, hf, tvb, 0, 0, &t);

    proto_item_set_generated(ti);
    return ti;
}

static void
show_serial(proto_tree *at, tvbuff_t *tvb, packet_info *pinfo, const eglink_info_t *info,
            const eglink_frame_t *fd)
{
    proto_item *ti;
    guint lost;

    if (fd->serial_status == SERIAL_FIRST)
        return;
    ti = add_generated_uint(at, hf_expected_serial, tvb, fd->expected_serial);
    lost = serial_lost(fd, info->serial);
    if (lost) {
        ti = add_generated_uint(at, hf_lost, tvb, lost);
        expert_add_info_format(pinfo, ti, &ei_serial_gap,
            "%u packet%s lost from this sender: serial %u expected, %u received",
            lost, lost == 1 ? "" : "s", fd->expected_serial, info->serial);
        col_append_fstr(pinfo->cinfo, COL_INFO, " [lost %u]", lost);
    }
}

/* The packet at which the deadline of a command (first sent in `frame`)
 * was seen passing unacknowledged. On the second pass and in the GUI the
 * warning is on the command's frame (show_command()) and this packet gets a
 * note naming the command. In one pass (tshark without -2, as CI runs it)
 * the command's frame is behind the reader already: this packet carries the
 * command's warning itself, so a severity filter or "-z expert" finds every
 * failed command. The [unacked] tag and the link are here on every pass: a
 * live capture colours and draws a row once, from the dissection after its
 * first pass, before any later packet can mark its command; this packet is
 * where a live packet list can show the failure, and the profile colours it
 * by the link. */
static void
show_failed(proto_tree *at, tvbuff_t *tvb, packet_info *pinfo, int dir, guint32 frame, guint32 command_id)
{
    proto_item *ti = add_generated_uint(at, hf_failed_command, tvb, frame);
    gboolean vrci = dir == EGLINK_DIR_IN;
    const char *what = vrci ? "VRCI" : "VRCO";
    const char *ack = vrci ? "VRAO" : "VRAI";
    guint timeout_ms = vrci ? eglink_pref_vrci_ack_timeout_ms : eglink_pref_vrco_ack_timeout_ms;

    col_append_str(pinfo->cinfo, COL_INFO, " [unacked]");
    if (PINFO_FD_VISITED(pinfo)) {
        expert_add_info_format(pinfo, ti, vrci ? &ei_vrci_deadline : &ei_vrco_deadline,
            "Deadline of %s command %u (frame %u) passed with no %s (%u ms)",
            what, command_id, frame, ack, timeout_ms);
        return;
    }
    expert_add_info_format(pinfo, ti, vrci ? &ei_vrci_unacked : &ei_vrco_unacked,
        "%s command %u (frame %u) not acknowledged by a %s within %u ms%s", what, command_id, frame, ack,
        timeout_ms, vrci ? ": the BU reports to the RU application that the command failed" : "");
}

static void
show_command(proto_tree *at, proto_item *aitem, tvbuff_t *tvb, packet_info *pinfo,
             const eglink_info_t *info, const eglink_frame_t *fd)
{
    const eglink_cmd_t *cmd = fd->cmd;
    const eglink_finding_t *late;
    proto_item *ti;
    const char *what = cmd->dir == EGLINK_DIR_IN ? "VRCI" : "VRCO";
    const char *ack = cmd->dir == EGLINK_DIR_IN ? "VRAO" : "VRAI";
    guint timeout_ms = cmd->dir == EGLINK_DIR_IN ? eglink_pref_vrci_ack_timeout_ms : eglink_pref_vrco_ack_timeout_ms;

    if (info->type == EGLINK_TYPE_VRCI || info->type == EGLINK_TYPE_VRCO) {
        if (fd->flags & FF_RETRANS) {
            ti = add_generated_uint(at, hf_retransmission_of, tvb, cmd->first_frame);
            expert_add_info_format(pinfo, ti, &ei_retransmission,
                "Retransmission of %s command %u", what, cmd->command_id);
            col_append_str(pinfo->cinfo, COL_INFO, " [Retransmission]");
        } else {
            expert_add_info_format(pinfo, aitem, &ei_command, "New %s command %u", what, cmd->command_id);
        }
        /* Known on the first pass only when the acknowledgement came first:
         * forward links, shown on the second pass and in the GUI. */
        if (cmd->ack_frame) {
            ti = add_generated_uint(at, hf_ack_in, tvb, cmd->ack_frame);
            proto_item_append_text(ti, " (%s)", ack);
        }
        /* The finding sits on the command itself (its first transmission),
         * linked to the packet at which the deadline was seen passing. */
        if (cmd->failed && cmd->deadline_frame && !(fd->flags & FF_RETRANS)) {
            ti = add_generated_uint(at, hf_deadline_in, tvb, cmd->deadline_frame);
            if (cmd->dir == EGLINK_DIR_IN)
                expert_add_info_format(pinfo, ti, &ei_vrci_unacked,
                    "VRCI command %u not acknowledged by a VRAO within %u ms (deadline at frame %u): "
                    "the BU reports to the RU application that the command failed",
                    cmd->command_id, eglink_pref_vrci_ack_timeout_ms, cmd->deadline_frame);
            else
                expert_add_info_format(pinfo, ti, &ei_vrco_unacked,
                    "VRCO command %u not acknowledged by a VRAI within %u ms (deadline at frame %u)",
                    cmd->command_id, eglink_pref_vrco_ack_timeout_ms, cmd->deadline_frame);
            col_append_str(pinfo->cinfo, COL_INFO, " [unacked]");
        }
    } else {
        ti = add_generated_uint(at, hf_ack_to, tvb, cmd->first_frame);
        proto_item_append_text(ti, " (%s command %u)", what, cmd->command_id);
        if (fd->flags & FF_DELTA)
            add_generated_time(at, hf_ack_time, tvb, fd->delta_ns);
        late = find_finding(fd, FND_LATE_ACK);
        /* A late acknowledgement that is itself the first packet past the
         * deadline: the command failed here, as at any other such packet. */
        if (late && cmd->deadline_frame == pinfo->num && !PINFO_FD_VISITED(pinfo))
            show_failed(at, tvb, pinfo, cmd->dir, cmd->first_frame, cmd->command_id);
        if (late) {
            expert_add_info_format(pinfo, ti, &ei_late_ack,
                "Acknowledges %s command %u %s after its first transmission, later than %u ms",
                what, cmd->command_id, ns_str_past(pinfo->pool, late->ns, timeout_ms), timeout_ms);
            col_append_str(pinfo->cinfo, COL_INFO, " [late ack]");
        } else if ((fd->flags & FF_FIRST_ACK) && (fd->flags & FF_DELTA)) {
            expert_add_info_format(pinfo, ti, &ei_ack, "Acknowledges %s command %u after %s",
                                   what, cmd->command_id, ns_str(pinfo->pool, fd->delta_ns));
        }
    }
}

/* The BU a packet belongs to, for filters and the profile's Device column:
 * its origin, also on a controller's packets from before an acknowledgement
 * joined it to its BU (known on the second pass and in the GUI only). */
static void
show_device(proto_tree *at, proto_item *aitem, tvbuff_t *tvb, packet_info *pinfo, const eglink_frame_t *fd)
{
    const char *device;
    proto_item *ti;

    if (!at)                    /* no tree: nothing to show, no text to format */
        return;
    if (fd->flags & FF_ORIGIN) {
        add_generated_uint(at, hf_bu_origin, tvb, fd->bu_origin);
        device = wmem_strdup_printf(pinfo->pool, "0x%04x", fd->bu_origin);
    } else if (!fd->bu && fd->ctrl && fd->ctrl->bu && fd->ctrl->bu->origin_known) {
        ti = add_generated_uint(at, hf_bu_origin, tvb, fd->ctrl->bu->origin);
        proto_item_append_text(ti, " (joined to this BU by a later acknowledgement)");
        proto_item_append_text(aitem, ", joined to BU 0x%04x later", fd->ctrl->bu->origin);
        device = wmem_strdup_printf(pinfo->pool, "0x%04x", fd->ctrl->bu->origin);
    } else {
        device = fd->bu ? fd->bu->name : "BU not known";
    }
    ti = proto_tree_add_string(at, hf_device, tvb, 0, 0, device);
    proto_item_set_generated(ti);
}

static const char *
plural(guint n, const char *one, const char *many)
{
    return n == 1 ? one : many;
}

static const char *const type_names[] = { "VRPI", "VRPO", "VRCI", "VRCO", "VRAI", "VRAO" };

/* Also on a packet that is not analysed (bad CRC or size): the clock is its own. */
static void
show_time_backwards(proto_tree *at, tvbuff_t *tvb, packet_info *pinfo, const eglink_finding_t *f)
{
    proto_item *ti = add_generated_uint(at, hf_time_backwards_after, tvb, f->frame);
    const char *t = ns_str(pinfo->pool, f->ns);

    expert_add_info_format(pinfo, ti, &ei_time_backwards,
        "Time went backwards by %s (clock step): this packet is older than the EG-Link packet "
        "before it; gap, age and deadline rules restart here", t);
    col_append_fstr(pinfo->cinfo, COL_INFO, " [time backwards %s]", t);
}

static void
show_wrong_port(proto_tree *at, tvbuff_t *tvb, packet_info *pinfo, const eglink_info_t *info, guint32 expected)
{
    proto_item *ti = add_generated_uint(at, hf_expected_port, tvb, expected);

    if (eglink_is_input(info->type))
        expert_add_info_format(pinfo, ti, &ei_wrong_port,
            "%s sent to UDP port %u, the output packet port: the BU sends VRPI, VRCI and VRAI to its "
            "input packet port (%u here, TS-0006 §2.2); analysed with this BU's packets",
            type_names[info->type], pinfo->destport, expected);
    else
        expert_add_info_format(pinfo, ti, &ei_wrong_port,
            "%s sent to UDP port %u%s: the machine controller sends VRPO, VRCO and VRAO to the "
            "BU's input port + 2 (%u here, TS-0006 §2.2); analysed with this controller's packets",
            type_names[info->type], pinfo->destport,
            pinfo->destport + 2 == expected ? ", the BU's input port" : "", expected);
    col_append_str(pinfo->cinfo, COL_INFO, " [wrong port]");
}

/* A controller packet analysed on a port of its own, where no BU is. One
 * pass cannot tell yet whether the controller turns up with a BU later
 * (an excerpt that starts with a packet it sent to a wrong port): said.
 * Once it has (eglink_ctrl_adopt(), the second pass and the GUI), the
 * packet is that BU's, on the wrong port. */
static void
show_orphan(proto_tree *at, proto_item *aitem, tvbuff_t *tvb, packet_info *pinfo, const eglink_info_t *info,
            const eglink_frame_t *fd)
{
    const eglink_ctrl_t *ctrl = fd->ctrl;

    if (!ctrl || fd->bu)
        return;
    if (ctrl->chan->own_port && !ctrl->chan->n_bus) {
        if (!PINFO_FD_VISITED(pinfo))
            expert_add_info_format(pinfo, aitem, &ei_not_joined,
                "%s sent to UDP port %u, where no BU has been seen: not joined to a BU yet (two passes "
                "join it to the BU its controller turns up with later)", type_names[info->type], pinfo->destport);
        return;
    }
    if (ctrl->adopted && pinfo->destport != ctrl->chan->port + 2 && !find_finding(fd, FND_WRONG_PORT))
        show_wrong_port(at, tvb, pinfo, info, ctrl->chan->port + 2);
}

/* The controller joined to its BU only for being alone with it on the
 * channel, which this packet, from a second BU or controller there, withdrew.
 * Also on a packet that is not analysed: the sender is on the channel. */
static void
show_withdrawn(packet_info *pinfo, proto_item *aitem, const eglink_finding_t *f)
{
    const eglink_ctrl_t *ctrl = *(eglink_ctrl_t **)wmem_array_index(eglink_ctrl_by_index, f->value);

    expert_add_info_format(pinfo, aitem, &ei_join_withdrawn,
        "Controller %s no longer joined to %s: only being alone with it on %s joined them, and "
        "this packet is a second %s's there: BU not known until a command acknowledged between "
        "them",
        address_to_str(pinfo->pool, &ctrl->addr), ctrl->alone_bu->name, ctrl->chan->where,
        f->ns ? "BU" : "controller");
}

static const char *const vrpo_break_names[] = { "a gap with no packet lost", "a repeat", "a step back" };

/* The VRPO rules of TS-0006 4.2 and 5.1.2. */
static void
show_vrpo_rule(proto_item *aitem, packet_info *pinfo, const eglink_info_t *info, const eglink_finding_t *f)
{
    switch ((eglink_finding_kind_t)f->kind) {
    case FND_VRPO_NUMBER:
        expert_add_info_format(pinfo, aitem, &ei_vrpo_number,
            "VRPO packet number %u, %u expected (%s): TS-0006 §4.2 increments it by one for each packet",
            info->packet_number, f->value, vrpo_break_names[f->ns < 3 ? f->ns : 0]);
        break;
    case FND_VRPO_INTERVAL:
        expert_add_info_format(pinfo, aitem, &ei_vrpo_interval,
            "VRPO %s after the previous one: TS-0006 §5.1.2 recommends a VRPO every %u to %u ms",
            ns_str_past(pinfo->pool, f->ns, f->ns < ms_to_ns(EGLINK_VRPO_INTERVAL_MIN_MS)
                                            ? EGLINK_VRPO_INTERVAL_MIN_MS : EGLINK_VRPO_INTERVAL_MAX_MS),
            EGLINK_VRPO_INTERVAL_MIN_MS, EGLINK_VRPO_INTERVAL_MAX_MS);
        break;
    case FND_BURST_SPREAD:
        expert_add_info_format(pinfo, aitem, &ei_burst_spread,
            "VRPO packet %u %s after the packet before it in its burst (more than %u ms): TS-0006 "
            "§5.1.2 sends the packets of a split VRPO without delay", info->packet_number,
            ns_str_past(pinfo->pool, f->ns, eglink_pref_burst_spread_ms), eglink_pref_burst_spread_ms);
        break;
    case FND_VRPO_NOT_FULL:
        expert_add_info_format(pinfo, aitem, &ei_vrpo_not_full,
            "VRPO packet %u (frame %u) carried %u bytes but its burst goes on with packet %u: "
            "TS-0006 §4.2: all packets of a burst but the last are full (%u bytes)",
            f->value & 0xFFFF, f->frame, f->value >> 16, info->packet_number, EGLINK_VRPO_FRAGMENT_MAX);
        break;
    default:
        break;
    }
}

/* The edge of the resend window (100 ms +- the tolerance) a resend
 * interval falls outside of. */
static guint
resend_edge_ms(gint64 ns)
{
    if (ns > ms_to_ns(EGLINK_RESEND_INTERVAL_MS))
        return EGLINK_RESEND_INTERVAL_MS + eglink_pref_resend_tolerance_ms;
    return eglink_pref_resend_tolerance_ms < EGLINK_RESEND_INTERVAL_MS
           ? EGLINK_RESEND_INTERVAL_MS - eglink_pref_resend_tolerance_ms : 0;
}

/* The command rules of TS-0006 4.3, 4.5, 5.1.3 and 5.1.4. */
static void
show_command_rule(proto_item *aitem, packet_info *pinfo, const eglink_info_t *info, const eglink_finding_t *f)
{
    gboolean vrci = (f->value >> 16) == EGLINK_DIR_IN;
    const char *what = vrci ? "VRCI" : "VRCO";
    const char *ack = vrci ? "VRAO" : "VRAI";
    const char *flow = vrci ? "5.1.3" : "5.1.4";
    guint id = f->value & 0xFFFF;
    guint timeout_ms = vrci ? eglink_pref_vrci_ack_timeout_ms : eglink_pref_vrco_ack_timeout_ms;

    switch ((eglink_finding_kind_t)f->kind) {
    case FND_RESEND_INTERVAL:
        expert_add_info_format(pinfo, aitem, &ei_resend_interval,
            "%s command %u resent %s after its previous transmission (frame %u): TS-0006 §%s "
            "resends it every %u ms (tolerance %u ms)", what, id, ns_str_past(pinfo->pool, f->ns, resend_edge_ms(f->ns)), f->frame,
            flow, EGLINK_RESEND_INTERVAL_MS, eglink_pref_resend_tolerance_ms);
        break;
    case FND_NOT_RESENT:
        expert_add_info_format(pinfo, aitem, &ei_not_resent,
            "%s command %u (frame %u) not resent for %s while unacknowledged: TS-0006 §%s "
            "resends it every %u ms until a %s", what, id, f->frame,
            ns_str_past(pinfo->pool, f->ns, EGLINK_RESEND_INTERVAL_MS + eglink_pref_resend_tolerance_ms), flow,
            EGLINK_RESEND_INTERVAL_MS, ack);
        break;
    case FND_RESENT_AFTER_ACK:
        expert_add_info_format(pinfo, aitem, &ei_resent_after_ack,
            "%s command %u resent after its %s (frame %u): TS-0006 §%s resends it only until "
            "acknowledged", what, id, ack, f->frame, flow);
        break;
    case FND_RESENT_AFTER_DEADLINE:
        expert_add_info_format(pinfo, aitem, &ei_resent_after_deadline,
            "%s command %u resent %s after its first transmission (frame %u), past its %u ms "
            "deadline: %s", what, id,
            ns_str_past(pinfo->pool, f->ns, timeout_ms), f->frame, timeout_ms,
            /* only 5.1.4 (VRCO) has the sender stop; 5.1.3 has the VRCI failed */
            vrci ? "TS-0006 §5.1.3 has the command failed by then"
                 : "TS-0006 §5.1.4 stops sending the command at the timeout");
        break;
    case FND_CMD_ID_SEQUENCE:
        expert_add_info_format(pinfo, aitem, &ei_command_id_sequence,
            "%s command ID %u after %u, %u expected: TS-0006 §%s numbers commands sequentially",
            what, info->command_id, (guint)f->ns, id, vrci ? "4.3" : "4.5");
        break;
    default:
        break;
    }
}

static void
show_findings(proto_tree *at, proto_item *aitem, tvbuff_t *tvb, packet_info *pinfo,
              const eglink_info_t *info, const eglink_frame_t *fd)
{
    const eglink_finding_t *f;
    proto_item *ti;
    const char *t;

    for (f = fd->findings; f; f = f->next) {
        /* (the gaps below: a VRPI's or a VRPO's, past its threshold) */
        t = ns_str_past(pinfo->pool, f->ns, f->kind == FND_VRPI_GAP || f->kind == FND_VRPI_MISSING
                                            ? eglink_pref_vrpi_gap_ms : eglink_pref_vrpo_gap_ms);
        switch ((eglink_finding_kind_t)f->kind) {
        case FND_REPEAT:
            ti = aitem;
            if (f->frame)
                ti = add_generated_uint(at, hf_repeat_of, tvb, f->frame);
            if (f->value == info->serial)
                expert_add_info_format(pinfo, ti, &ei_serial_repeat,
                    "Repeated packet: serial %u was already received; not analysed further",
                    info->serial);
            else
                expert_add_info_format(pinfo, ti, &ei_serial_repeat,
                    "Repeated or reordered packet: serial %u is older than the last one received (%u); "
                    "not analysed further", info->serial, f->value);
            col_append_str(pinfo->cinfo, COL_INFO, " [Repeated]");
            break;
        case FND_RESTART:
            expert_add_info_format(pinfo, aitem, &ei_serial_restart,
                "Serial jumped back from %u to %u: the sender restarted?", f->value, info->serial);
            break;
        case FND_ORIGIN:
            expert_add_info_format(pinfo, aitem, &ei_origin_changed,
                "Origin changed from 0x%04x to 0x%04x at the same address: the BU was replaced "
                "or reconfigured", f->value, info->origin);
            break;
        case FND_BU_STATE:
            expert_add_info_format(pinfo, aitem, &ei_bu_state_changed,
                "BU state changed from %s (0x%02x) to %s (0x%02x)",
                eglink_bu_state_name((guint8)f->value), f->value,
                eglink_bu_state_name(info->bu_state), info->bu_state);
            break;
        case FND_VRPI_GAP:
            ti = add_generated_uint(at, hf_last_vrpi, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_vrpi_gap,
                "No VRPI for %s (more than %u ms): the machine controller should have flagged "
                "an error", t, eglink_pref_vrpi_gap_ms);
            col_append_fstr(pinfo->cinfo, COL_INFO, " [gap %s]", t);
            break;
        case FND_VRPO_GAP:
            ti = add_generated_uint(at, hf_last_vrpo, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_vrpo_gap,
                "No VRPO for %s (more than %u ms): the BU flags an error and, with an RU armed, "
                "opens the ES-Link relays", t, eglink_pref_vrpo_gap_ms);
            col_append_fstr(pinfo->cinfo, COL_INFO, " [gap %s]", t);
            break;
        case FND_VRPI_MISSING:
            ti = add_generated_uint(at, hf_last_vrpi, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_vrpi_missing,
                "No VRPI from this BU for %s (more than %u ms)", t, eglink_pref_vrpi_gap_ms);
            col_append_fstr(pinfo->cinfo, COL_INFO, " [no VRPI %s]", t);
            break;
        case FND_VRPO_MISSING:
            ti = add_generated_uint(at, hf_last_vrpo, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_vrpo_missing,
                "No VRPO to this BU for %s (more than %u ms): the BU flags an error and, with "
                "an RU armed, opens the ES-Link relays", t, eglink_pref_vrpo_gap_ms);
            col_append_fstr(pinfo->cinfo, COL_INFO, " [no VRPO %s]", t);
            break;
        case FND_FAILED_VRCI:
            show_failed(at, tvb, pinfo, EGLINK_DIR_IN, f->frame, f->value);
            break;
        case FND_FAILED_VRCO:
            show_failed(at, tvb, pinfo, EGLINK_DIR_OUT, f->frame, f->value);
            break;
        case FND_UNKNOWN_ACK:
            expert_add_info_format(pinfo, aitem, &ei_unknown_ack,
                "Acknowledges %s command %u, which is not in the capture",
                info->type == EGLINK_TYPE_VRAO ? "VRCI" : "VRCO", f->value);
            break;
        case FND_BURST_INCOMPLETE:
            ti = add_generated_uint(at, hf_incomplete_burst, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_burst_incomplete,
                "VRPO burst is incomplete (packet %u %s): its periodic data cannot be "
                "reassembled", f->value & 0xFFFF,
                (f->value & EGLINK_BURST_CUT) ? "cut by the capture" : "missing");
            break;
        case FND_BURST_SIZE:
            expert_add_info_format(pinfo, aitem, &ei_burst_size,
                "VRPO burst carries %u bytes of periodic data; the periodic data size "
                "preference says %u", f->value, (guint)f->ns);
            break;
        case FND_SHARED_GROUP:
            expert_add_info_format(pinfo, aitem, &ei_shared_group,
                "%s is shared by several BUs or controllers (so far %u %s%s): each "
                "controller's VRPO and VRCO reach every BU on it; give each BU a group or port "
                "of its own", fd->bu ? fd->bu->chan->where : fd->ctrl->chan->where,
                f->value, plural(f->value, "BU", "BUs"),
                f->ns == 0 ? "" : wmem_strdup_printf(pinfo->pool, " and %u %s", (guint)f->ns,
                                                     plural((guint)f->ns, "controller", "controllers")));
            col_append_str(pinfo->cinfo, COL_INFO, " [shared group]");
            break;
        case FND_CORRUPTED:
            ti = add_generated_uint(at, hf_corrupted_in, tvb, f->frame);
            expert_add_info_format(pinfo, ti, &ei_serial_corrupted,
                "Serial %u arrived with a %s, frame %u: not counted as lost",
                f->value & 0xFFFF, (f->value & EGLINK_CORRUPTED_CRC) ? "bad CRC" : "wrong size", f->frame);
            break;
        case FND_WRONG_PORT:
            show_wrong_port(at, tvb, pinfo, info, f->value);
            break;
        case FND_TIME_BACKWARDS:
            show_time_backwards(at, tvb, pinfo, f);
            break;
        case FND_JOIN_WITHDRAWN:
            show_withdrawn(pinfo, aitem, f);
            break;
        case FND_VRPO_NUMBER:
        case FND_VRPO_INTERVAL:
        case FND_BURST_SPREAD:
        case FND_VRPO_NOT_FULL:
            show_vrpo_rule(aitem, pinfo, info, f);
            break;
        case FND_RESEND_INTERVAL:
        case FND_NOT_RESENT:
        case FND_RESENT_AFTER_ACK:
        case FND_RESENT_AFTER_DEADLINE:
        case FND_CMD_ID_SEQUENCE:
            show_command_rule(aitem, pinfo, info, f);
            break;
        case FND_REVISION:
            expert_add_info_format(pinfo, aitem, &ei_revision_ignored,
                "Revision %u: kept out of the analysis, as TS-0006 §5.1.5 has receivers ignore "
                "unsupported header values (its serial is counted)", f->value);
            break;
        case FND_LATE_ACK:      /* shown with the command link */
        case FND_BURST_DONE:    /* shown with the reassembly */
            break;
        }
    }
}

/* The analysis of one frame, from its record: on every pass. */
void
show_frame(tvbuff_t *tvb, packet_info *pinfo, proto_tree *eglink_tree, const eglink_info_t *info,
           const eglink_frame_t *fd)
{
    proto_item *aitem;
    proto_tree *at;

    aitem = proto_tree_add_item(eglink_tree, hf_analysis, tvb, 0, 0, ENC_NA);
    proto_item_set_generated(aitem);
    at = proto_item_add_subtree(aitem, ett_analysis);
    proto_item_append_text(aitem, ": %s", fd->bu ? fd->bu->name : fd->ctrl->name);
    if (fd->bu)
        add_generated_uint(at, hf_bu_stream, tvb, fd->bu->index);
    if (fd->bu && fd->ctrl)
        proto_item_set_generated(proto_tree_add_boolean(at, hf_joined_alone, tvb, 0, 0, TRUE));
    show_device(at, aitem, tvb, pinfo, fd);

    if (fd->flags & FF_INVALID) {
        const eglink_finding_t *f = find_finding(fd, FND_TIME_BACKWARDS);

        proto_item_append_text(aitem, " (not analysed: CRC or size check failed)");
        if (f)
            show_time_backwards(at, tvb, pinfo, f);
        f = find_finding(fd, FND_JOIN_WITHDRAWN);
        if (f)
            show_withdrawn(pinfo, aitem, f);
    } else {
        show_serial(at, tvb, pinfo, info, fd);
        if ((fd->flags & FF_DELTA) && info->type == EGLINK_TYPE_VRPI)
            add_generated_time(at, hf_time_since_prev_vrpi, tvb, fd->delta_ns);
        if ((fd->flags & FF_DELTA) && info->type == EGLINK_TYPE_VRPO)
            add_generated_time(at, hf_time_since_prev_vrpo, tvb, fd->delta_ns);
        if (fd->cmd)
            show_command(at, aitem, tvb, pinfo, info, fd);
        show_findings(at, aitem, tvb, pinfo, info, fd);
        show_orphan(at, aitem, tvb, pinfo, info, fd);
        show_reassembly(tvb, pinfo, eglink_tree, info, fd);
    }
}

/* ---------------------------------------------------------------------- */

void
eglink_findings_register(int proto)
{
    static hf_register_info hf[] = {
        { &hf_analysis,
          { "Analysis", "eglink.analysis", FT_NONE, BASE_NONE, NULL, 0x0,
            "Conversation analysis of this packet within its BU", HFILL } },
        { &hf_bu_stream,
          { "BU stream index", "eglink.analysis.bu_stream", FT_UINT32, BASE_DEC, NULL, 0x0,
            "Number of the BU (origin and address, on its group or address pair and input "
            "port) this packet belongs to, from 0 in order of appearance; absent on a "
            "controller packet whose BU is not known yet", HFILL } },
        { &hf_bu_origin,
          { "BU origin", "eglink.analysis.bu_origin", FT_UINT16, BASE_HEX, NULL, 0x0,
            "Unique ID of the BU this packet belongs to, learned from its VRPI/VRCI/VRAI "
            "(also on the packets of the machine controller joined to it, which carry "
            "origin 0; on a controller joined later, from the second pass on)", HFILL } },
        { &hf_device,
          { "Device", "eglink.analysis.device", FT_STRING, BASE_NONE, NULL, 0x0,
            "The BU this packet belongs to: its origin (0x1001), or \"BU not known\" on the "
            "packets of a controller not joined to a BU", HFILL } },
        { &hf_joined_alone,
          { "Joined for being alone", "eglink.analysis.joined_alone", FT_BOOLEAN, BASE_NONE, NULL, 0x0,
            "A controller packet joined to its BU only because the two are the only controller "
            "and the only BU of the channel so far (no command acknowledged between them yet); "
            "a second BU or controller there withdraws it", HFILL } },
        { &hf_expected_serial,
          { "Expected serial", "eglink.analysis.expected_serial", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Serial that follows the previous packet of the same sender", HFILL } },
        { &hf_lost,
          { "Lost packets", "eglink.analysis.lost", FT_UINT16, BASE_DEC, NULL, 0x0,
            "Packets of this sender missing just before this one (serial gap)", HFILL } },
        { &hf_repeat_of,
          { "Repeat of frame", "eglink.analysis.repeat_of", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_DUP_ACK), 0x0,
            "Earlier frame with the same sender and serial", HFILL } },
        { &hf_time_since_prev_vrpi,
          { "Time since previous VRPI", "eglink.analysis.time_since_prev_vrpi", FT_RELATIVE_TIME,
            BASE_NONE, NULL, 0x0, "Time since the previous VRPI of this BU", HFILL } },
        { &hf_time_since_prev_vrpo,
          { "Time since previous VRPO", "eglink.analysis.time_since_prev_vrpo", FT_RELATIVE_TIME,
            BASE_NONE, NULL, 0x0, "Time since the previous VRPO to this BU", HFILL } },
        { &hf_retransmission_of,
          { "Retransmission of frame", "eglink.analysis.retransmission_of", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_RETRANS_PREV), 0x0,
            "First transmission of this command (same Command ID)", HFILL } },
        { &hf_ack_in,
          { "Acknowledged in frame", "eglink.analysis.ack_in", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_RESPONSE), 0x0,
            "First VRAO (for a VRCI) or VRAI (for a VRCO) acknowledging this command", HFILL } },
        { &hf_ack_to,
          { "Acknowledges frame", "eglink.analysis.ack_to", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_ACK), 0x0,
            "First transmission of the command this packet acknowledges", HFILL } },
        { &hf_ack_time,
          { "Acknowledgement time", "eglink.analysis.ack_time", FT_RELATIVE_TIME, BASE_NONE,
            NULL, 0x0, "Time from the first transmission of the command to this acknowledgement",
            HFILL } },
        { &hf_failed_command,
          { "Unacknowledged command", "eglink.analysis.failed_command", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "Command whose acknowledgement deadline passed before this packet", HFILL } },
        { &hf_deadline_in,
          { "Acknowledgement deadline passed in frame", "eglink.analysis.deadline_in", FT_FRAMENUM,
            BASE_NONE, FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "First packet of the BU or its controller after this command's acknowledgement deadline "
            "passed unacknowledged (second pass and GUI)", HFILL } },
        { &hf_incomplete_burst,
          { "Incomplete VRPO burst", "eglink.analysis.incomplete_burst", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "First packet of a split VRPO burst that cannot be reassembled", HFILL } },
        { &hf_last_vrpi,
          { "Last VRPI before the gap", "eglink.analysis.last_vrpi", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "The BU's VRPI before a VRPI gap (eglink.analysis.vrpi_gap, vrpi_missing)", HFILL } },
        { &hf_last_vrpo,
          { "Last VRPO before the gap", "eglink.analysis.last_vrpo", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "The controller's VRPO before a VRPO gap (eglink.analysis.vrpo_gap, vrpo_missing)", HFILL } },

        { &hf_corrupted_in,
          { "Serial arrived corrupted in frame", "eglink.analysis.corrupted_in", FT_FRAMENUM, BASE_NONE,
            FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "A packet of this sender's serial gap that arrived with a bad CRC or size: not lost",
            HFILL } },
        { &hf_expected_port,
          { "Expected UDP port", "eglink.analysis.expected_port", FT_UINT16, BASE_DEC, NULL, 0x0,
            "The port a controller packet sent to another port belongs on: the BU's input port + 2",
            HFILL } },
        { &hf_time_backwards_after,
          { "Time went backwards after frame", "eglink.analysis.time_backwards_after", FT_FRAMENUM,
            BASE_NONE, FRAMENUM_TYPE(FT_FRAMENUM_NONE), 0x0,
            "The EG-Link packet before a clock step back, newer than this one", HFILL } },
    };
    static gint *ett[] = {
        &ett_analysis,
    };
    static ei_register_info ei[] = {
        { &ei_serial_gap,
          { "eglink.analysis.serial_gap", PI_SEQUENCE, PI_WARN,
            "Packets lost: serial gap", EXPFILL } },
        { &ei_serial_repeat,
          { "eglink.analysis.serial_repeat", PI_SEQUENCE, PI_WARN,
            "Repeated packet: serial already received", EXPFILL } },
        { &ei_serial_restart,
          { "eglink.analysis.serial_restart", PI_SEQUENCE, PI_NOTE,
            "Serial jumped back: the sender restarted", EXPFILL } },
        { &ei_vrpi_gap,
          { "eglink.analysis.vrpi_gap", PI_SEQUENCE, PI_ERROR,
            "VRPI gap longer than the threshold", EXPFILL } },
        { &ei_vrpo_gap,
          { "eglink.analysis.vrpo_gap", PI_SEQUENCE, PI_ERROR,
            "VRPO gap longer than the threshold", EXPFILL } },
        { &ei_vrpi_missing,
          { "eglink.analysis.vrpi_missing", PI_SEQUENCE, PI_ERROR,
            "No VRPI from the BU for longer than the threshold", EXPFILL } },
        { &ei_vrpo_missing,
          { "eglink.analysis.vrpo_missing", PI_SEQUENCE, PI_ERROR,
            "No VRPO to the BU for longer than the threshold", EXPFILL } },
        { &ei_retransmission,
          { "eglink.analysis.retransmission", PI_SEQUENCE, PI_NOTE,
            "Command retransmission (same Command ID)", EXPFILL } },
        { &ei_vrci_unacked,
          { "eglink.analysis.vrci_unacked", PI_SEQUENCE, PI_WARN,
            "VRCI not acknowledged in time: the command failed", EXPFILL } },
        { &ei_vrco_unacked,
          { "eglink.analysis.vrco_unacked", PI_SEQUENCE, PI_WARN,
            "VRCO not acknowledged in time", EXPFILL } },
        { &ei_vrci_deadline,
          { "eglink.analysis.vrci_deadline", PI_SEQUENCE, PI_NOTE,
            "Deadline of a VRCI passed with no VRAO", EXPFILL } },
        { &ei_vrco_deadline,
          { "eglink.analysis.vrco_deadline", PI_SEQUENCE, PI_NOTE,
            "Deadline of a VRCO passed with no VRAI", EXPFILL } },
        { &ei_late_ack,
          { "eglink.analysis.late_ack", PI_SEQUENCE, PI_WARN,
            "Acknowledgement after the deadline", EXPFILL } },
        { &ei_unknown_ack,
          { "eglink.analysis.unknown_ack", PI_SEQUENCE, PI_CHAT,
            "Acknowledges a command that is not in the capture", EXPFILL } },
        { &ei_bu_state_changed,
          { "eglink.analysis.bu_state_changed", PI_SEQUENCE, PI_NOTE,
            "BU state changed", EXPFILL } },
        { &ei_origin_changed,
          { "eglink.analysis.origin_changed", PI_SEQUENCE, PI_WARN,
            "Another origin from the same BU address", EXPFILL } },
        { &ei_burst_incomplete,
          { "eglink.analysis.burst_incomplete", PI_REASSEMBLE, PI_WARN,
            "Split VRPO burst incomplete", EXPFILL } },
        { &ei_burst_size,
          { "eglink.analysis.burst_size", PI_REASSEMBLE, PI_WARN,
            "VRPO burst size differs from the periodic data size preference", EXPFILL } },
        { &ei_shared_group,
          { "eglink.analysis.shared_group", PI_SEQUENCE, PI_WARN,
            "Several BUs or controllers on one group and port", EXPFILL } },
        { &ei_command,
          { "eglink.analysis.command", PI_SEQUENCE, PI_CHAT,
            "New command (first transmission)", EXPFILL } },
        { &ei_ack,
          { "eglink.analysis.ack", PI_SEQUENCE, PI_CHAT,
            "Command acknowledged in time", EXPFILL } },
        { &ei_serial_corrupted,
          { "eglink.analysis.serial_corrupted", PI_SEQUENCE, PI_NOTE,
            "A serial of the gap arrived with a bad CRC or size: not lost", EXPFILL } },
        { &ei_wrong_port,
          { "eglink.analysis.wrong_port", PI_PROTOCOL, PI_WARN,
            "Controller packet on another UDP port than the BU's input port + 2", EXPFILL } },
        { &ei_time_backwards,
          { "eglink.analysis.time_backwards", PI_SEQUENCE, PI_WARN,
            "Time went backwards (clock step): rules restart here", EXPFILL } },
        { &ei_vrpo_number,
          { "eglink.analysis.vrpo_number", PI_SEQUENCE, PI_WARN,
            "VRPO packet number breaks the controller's numbering (TS-0006 4.2)", EXPFILL } },
        { &ei_vrpo_interval,
          { "eglink.analysis.vrpo_interval", PI_SEQUENCE, PI_NOTE,
            "VRPO interval outside the recommended 50 to 200 ms (TS-0006 5.1.2)", EXPFILL } },
        { &ei_burst_spread,
          { "eglink.analysis.burst_spread", PI_SEQUENCE, PI_NOTE,
            "Packets of a split VRPO burst spread out (TS-0006 5.1.2)", EXPFILL } },
        { &ei_vrpo_not_full,
          { "eglink.analysis.vrpo_not_full", PI_PROTOCOL, PI_WARN,
            "A VRPO packet that is not the last of its burst is not full (TS-0006 4.2)", EXPFILL } },
        { &ei_resend_interval,
          { "eglink.analysis.resend_interval", PI_SEQUENCE, PI_NOTE,
            "Command resent at another interval than 100 ms (TS-0006 5.1.3, 5.1.4)", EXPFILL } },
        { &ei_not_resent,
          { "eglink.analysis.not_resent", PI_SEQUENCE, PI_WARN,
            "Unacknowledged command not resent within 100 ms (TS-0006 5.1.3, 5.1.4)", EXPFILL } },
        { &ei_resent_after_ack,
          { "eglink.analysis.resent_after_ack", PI_SEQUENCE, PI_NOTE,
            "Command resent after its acknowledgement (TS-0006 5.1.3, 5.1.4)", EXPFILL } },
        { &ei_resent_after_deadline,
          { "eglink.analysis.resent_after_deadline", PI_SEQUENCE, PI_NOTE,
            "Command resent after its acknowledgement timeout (TS-0006 5.1.3, 5.1.4)", EXPFILL } },
        { &ei_command_id_sequence,
          { "eglink.analysis.command_id_sequence", PI_SEQUENCE, PI_WARN,
            "Command ID not the previous one + 1 (TS-0006 4.3, 4.5)", EXPFILL } },
        { &ei_revision_ignored,
          { "eglink.analysis.revision_ignored", PI_PROTOCOL, PI_NOTE,
            "Packet of another header revision kept out of the analysis (TS-0006 5.1.5)", EXPFILL } },
        { &ei_join_withdrawn,
          { "eglink.analysis.join_withdrawn", PI_SEQUENCE, PI_NOTE,
            "A controller joined to its BU only for being alone with it on the channel: no longer, "
            "with a second BU or controller there", EXPFILL } },
        { &ei_not_joined,
          { "eglink.analysis.not_joined", PI_SEQUENCE, PI_NOTE,
            "Controller packet on a port where no BU has been seen: not joined to a BU yet (one pass)",
            EXPFILL } },
    };
    expert_module_t *expert;

    proto_register_field_array(proto, hf, array_length(hf));
    proto_register_subtree_array(ett, array_length(ett));
    expert = expert_register_protocol(proto);
    expert_register_field_array(expert, ei, array_length(ei));
}

/* eglink-timing.c
 * The time of periodic packets (twin: lua/vrshark/eglink_timing.luam): the
 * interval from one VRPI of a BU, or VRPO of a controller, to the next and
 * its gaps; the BU state periods of the VRPI; the deadlines a packet's time
 * shows passing (periodic packets stopped, commands unacknowledged); the
 * clock stepping back, after which every time measured starts again.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-shared.h"

#include "eglink-compat.h"

/* The time of the latest EG-Link packet, to see the clock step back. */
static nstime_t eglink_last_ts;
static guint32 eglink_last_ts_frame;   /* 0: none yet */

void
eglink_timing_init(void)
{
    eglink_last_ts_frame = 0;
    nstime_set_zero(&eglink_last_ts);
}

/* The clock stepped back: every time the analysis measures (intervals,
 * periodic packets missing, command deadlines, BU state periods) starts
 * again from now. */
static void
sender_restart_clock(eglink_sender_t *s, const nstime_t *now)
{
    int i;

    if (s->last_periodic_frame) {
        s->last_periodic_ts = *now;
        s->clock_restart = TRUE;
    }
    for (i = 0; i < EGLINK_CMD_SLOTS; i++) {
        eglink_cmd_t *cmd = s->cmds[i];
        if (cmd && !cmd->ack_frame && !cmd->failed) {
            cmd->first_ts = cmd->last_ts = *now;
            cmd->clock_step = TRUE;
            cmd->resend_reported = TRUE;    /* its resends cannot be timed across the step */
        }
    }
}

static void
restart_clock(const nstime_t *now)
{
    guint i;

    for (i = 0; eglink_bu_by_index && i < wmem_array_get_count(eglink_bu_by_index); i++) {
        eglink_bu_t *bu = *(eglink_bu_t **)wmem_array_index(eglink_bu_by_index, i);
        sender_restart_clock(&bu->s, now);
        bu->state_since = *now;
        bu->state_since_step = TRUE;
    }
    for (i = 0; eglink_ctrl_by_index && i < wmem_array_get_count(eglink_ctrl_by_index); i++) {
        eglink_ctrl_t *ctrl = *(eglink_ctrl_t **)wmem_array_index(eglink_ctrl_by_index, i);
        sender_restart_clock(&ctrl->s, now);
        ctrl->burst.have_start_ts = FALSE;
    }
}

/* Time going backwards from one EG-Link packet to the next (a clock set
 * back while capturing, or captures of two clocks merged) is a finding on
 * the packet where it happens, and the rules that measure time restart
 * there. Going back less than EGLINK_CLOCK_JITTER_NS is not: the latest
 * time is kept. */
void
check_clock(packet_info *pinfo, eglink_frame_t *fd)
{
    gint64 back = eglink_last_ts_frame ? ns_signed(&eglink_last_ts, &pinfo->abs_ts) : 0;

    if (back > EGLINK_CLOCK_JITTER_NS) {
        add_finding(fd, FND_TIME_BACKWARDS, eglink_last_ts_frame, 0, back);
        restart_clock(&pinfo->abs_ts);
    } else if (back > 0) {
        return;
    }
    eglink_last_ts = pinfo->abs_ts;
    eglink_last_ts_frame = pinfo->num;
}

/* Periodic packets of one sender that stopped for longer than the threshold. */
static void
check_periodic(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, guint threshold_ms,
               eglink_finding_kind_t kind)
{
    gint64 age;

    if (!s->last_periodic_frame || s->periodic_missing_reported)
        return;
    age = ns_between(&pinfo->abs_ts, &s->last_periodic_ts);
    if (age > ms_to_ns(threshold_ms)) {
        s->periodic_missing_reported = TRUE;
        add_finding(fd, kind, s->last_periodic_frame, 0, age);
    }
}

/* Reports what a one-pass reader learns from the time of this packet alone:
 * periodic packets that stopped, commands whose deadline passed. A packet
 * speaks for its BU and the controllers joined to it; a controller whose
 * BU is not known speaks for itself only. */
void
check_deadlines(eglink_chan_t *chan, eglink_bu_t *bu, eglink_ctrl_t *sender, eglink_frame_t *fd,
                packet_info *pinfo, const eglink_info_t *info)
{
    eglink_type_t type = info->type;
    gint32 vrci_id = type == EGLINK_TYPE_VRCI && info->has_command_id ? info->command_id : -1;
    gint32 vrco_id = type == EGLINK_TYPE_VRCO && info->has_command_id ? info->command_id : -1;
    eglink_ctrl_t *ctrl;

    if (bu && type != EGLINK_TYPE_VRPI)
        check_periodic(&bu->s, fd, pinfo, eglink_pref_vrpi_gap_ms, FND_VRPI_MISSING);
    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next) {
        if (ctrl != sender && (!bu || ctrl->bu != bu))
            continue;
        if (!(ctrl == sender && type == EGLINK_TYPE_VRPO))
            check_periodic(&ctrl->s, fd, pinfo, eglink_pref_vrpo_gap_ms, FND_VRPO_MISSING);
    }
    if (bu)
        check_commands(&bu->s, fd, pinfo, EGLINK_DIR_IN, sender ? -1 : vrci_id);
    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next)
        if (ctrl == sender || (bu && ctrl->bu == bu))
            check_commands(&ctrl->s, fd, pinfo, EGLINK_DIR_OUT, ctrl == sender ? vrco_id : -1);
}

/* VRPI of a BU or VRPO of a controller: the interval since the previous one. */
void
track_interval(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, guint threshold_ms,
               eglink_finding_kind_t gap)
{
    if (s->last_periodic_frame && !s->clock_restart) {
        fd->delta_ns = ns_between(&pinfo->abs_ts, &s->last_periodic_ts);
        fd->flags |= FF_DELTA;
        if (fd->delta_ns > ms_to_ns(threshold_ms))
            add_finding(fd, gap, s->last_periodic_frame, 0, fd->delta_ns);
    }
    s->last_periodic_frame = pinfo->num;
    s->last_periodic_ts = pinfo->abs_ts;
    s->periodic_missing_reported = FALSE;
    s->clock_restart = FALSE;
}

void
track_vrpi(eglink_bu_t *bu, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info)
{
    track_interval(&bu->s, fd, pinfo, eglink_pref_vrpi_gap_ms, FND_VRPI_GAP);
    if (info->has_bu_state) {
        if (bu->have_bu_state) {
            /* The finding carries the length of the period that ends here
             * (for Statistics > EG-Link). */
            if (bu->bu_state != info->bu_state) {
                /* (-1: its length is not known, the clock stepped back) */
                add_finding(fd, FND_BU_STATE, 0, bu->bu_state,
                            bu->state_since_step ? -1 : ns_between(&pinfo->abs_ts, &bu->state_since));
                bu->state_since = pinfo->abs_ts;
                bu->state_since_step = FALSE;
            }
        } else {
            bu->state_since = pinfo->abs_ts;
        }
        bu->have_bu_state = TRUE;
        bu->bu_state = info->bu_state;
    }
}

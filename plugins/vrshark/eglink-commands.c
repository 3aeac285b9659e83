/* eglink-commands.c
 * Commands and their acknowledgements (twin: lua/vrshark/eglink_commands.luam):
 * a VRCI or VRCO with its retransmissions and their 100 ms rhythm, its
 * Command ID in sequence, the VRAO or VRAI that acknowledges it (and joins a
 * controller to its BU), the deadline that passes without one, and the
 * acknowledgements a controller sent on a port of its own before it turned
 * up with its BU.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-shared.h"

#include "eglink-compat.h"

static gint64
ack_timeout_ns(int dir)
{
    return ms_to_ns(dir == EGLINK_DIR_IN ? eglink_pref_vrci_ack_timeout_ms : eglink_pref_vrco_ack_timeout_ms);
}

static gint64
resend_limit_ns(void)
{
    return ms_to_ns(EGLINK_RESEND_INTERVAL_MS + eglink_pref_resend_tolerance_ms);
}

/* TS-0006 5.1.3, 5.1.4: a command is resent every 100 ms until it is
 * acknowledged (or its timeout passes). Flagged once per command, on the
 * first packet of its BU or controller more than 100 ms + the tolerance
 * after its latest transmission while it is unacknowledged, when that
 * resend was due before its deadline. */
static void
check_resend_due(eglink_cmd_t *cmd, eglink_frame_t *fd, packet_info *pinfo, int dir)
{
    gint64 since, interval = ms_to_ns(EGLINK_RESEND_INTERVAL_MS);

    if (cmd->ack_frame || cmd->failed || cmd->resend_reported)
        return;
    since = ns_between(&pinfo->abs_ts, &cmd->last_ts);
    if (since <= resend_limit_ns())
        return;
    if (ns_between(&cmd->last_ts, &cmd->first_ts) + interval >= ack_timeout_ns(dir))
        return;                 /* the next resend would fall past the deadline */
    cmd->resend_reported = TRUE;
    add_finding(fd, FND_NOT_RESENT, cmd->last_frame, cmd->command_id | ((guint32)dir << 16), since);
}

/* Commands of one sender whose deadline (or resend) passed before now.
 * own_id: the Command ID of this packet when it is a VRCI/VRCO of this
 * sender (its resend is timed by track_command()), else -1. */
void
check_commands(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, int dir, gint32 own_id)
{
    gint64 timeout = ack_timeout_ns(dir);
    int i;

    for (i = 0; i < EGLINK_CMD_SLOTS; i++) {
        eglink_cmd_t *cmd = s->cmds[i];
        gint64 age;

        if (cmd && (gint32)cmd->command_id != own_id)
            check_resend_due(cmd, fd, pinfo, dir);
        /* The acknowledgement this packet carries, even late, is not a
         * deadline passing unnoticed: track_ack() records it. */
        if (!cmd || cmd->ack_frame || cmd->failed || cmd == fd->cmd)
            continue;
        age = ns_between(&pinfo->abs_ts, &cmd->first_ts);
        if (age > timeout) {
            cmd->failed = TRUE;
            cmd->deadline_frame = pinfo->num;
            add_finding(fd, dir == EGLINK_DIR_IN ? FND_FAILED_VRCI : FND_FAILED_VRCO,
                        cmd->first_frame, cmd->command_id, age);
        }
    }
}

/* The most recent command of this sender with this ID. */
static eglink_cmd_t *
find_command(eglink_sender_t *s, guint16 command_id)
{
    eglink_cmd_t *best = NULL;
    int i;

    for (i = 0; i < EGLINK_CMD_SLOTS; i++) {
        eglink_cmd_t *cmd = s->cmds[i];
        if (cmd && cmd->command_id == command_id &&
            (!best || cmd->first_frame > best->first_frame))
            best = cmd;
    }
    return best;
}

/* TS-0006 5.1.3, 5.1.4: a retransmission comes 100 ms after the previous
 * transmission (within the tolerance), and only while the command waits for
 * its acknowledgement: not after it, nor after the deadline. */
static void
check_resend(const eglink_cmd_t *cmd, eglink_frame_t *fd, packet_info *pinfo, int dir)
{
    guint32 value = cmd->command_id | ((guint32)dir << 16);
    gint64 interval = ns_between(&pinfo->abs_ts, &cmd->last_ts);
    gint64 off = interval - ms_to_ns(EGLINK_RESEND_INTERVAL_MS);

    if (cmd->ack_frame) {
        add_finding(fd, FND_RESENT_AFTER_ACK, cmd->ack_frame, value, 0);
        return;
    }
    if (cmd->failed) {
        add_finding(fd, FND_RESENT_AFTER_DEADLINE, cmd->first_frame, value,
                    ns_between(&pinfo->abs_ts, &cmd->first_ts));
        return;
    }
    if (!cmd->clock_step && (off > ms_to_ns(eglink_pref_resend_tolerance_ms) || -off > ms_to_ns(eglink_pref_resend_tolerance_ms)))
        add_finding(fd, FND_RESEND_INTERVAL, cmd->last_frame, value, interval);
}

/* TS-0006 4.3, 4.5: a sender numbers its commands sequentially: a new
 * command's ID is the previous one + 1 (65535 is followed by 0). The first
 * command of a sender, or the first after it restarted, sets the count. */
static void
check_command_id(eglink_sender_t *s, eglink_frame_t *fd, int dir, guint16 command_id)
{
    guint16 expected = (guint16)(s->last_cmd_id + 1);

    if (s->have_cmd_id && command_id != expected)
        add_finding(fd, FND_CMD_ID_SEQUENCE, 0, expected | ((guint32)dir << 16), s->last_cmd_id);
    s->have_cmd_id = TRUE;
    s->last_cmd_id = command_id;
}

void
track_command(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, int dir, guint16 command_id)
{
    eglink_cmd_t *cmd = find_command(s, command_id);

    /* Same Command ID, sent again while the sender may still be waiting for
     * its acknowledgement: a retransmission. Much later it is a new command
     * that reuses the ID (wrap-around, restarted sender). */
    if (cmd && ns_between(&pinfo->abs_ts, &cmd->last_ts) <= ack_timeout_ns(dir)) {
        fd->flags |= FF_RETRANS;
        check_resend(cmd, fd, pinfo, dir);
        cmd->last_ts = pinfo->abs_ts;
        cmd->last_frame = pinfo->num;
    } else {
        check_command_id(s, fd, dir, command_id);
        cmd = wmem_new0(wmem_file_scope(), eglink_cmd_t);
        cmd->first_ts = pinfo->abs_ts;
        cmd->last_ts = pinfo->abs_ts;
        cmd->first_frame = pinfo->num;
        cmd->last_frame = pinfo->num;
        cmd->command_id = command_id;
        cmd->dir = (guint8)dir;
        s->cmds[s->cmd_next] = cmd;
        s->cmd_next = (s->cmd_next + 1) % EGLINK_CMD_SLOTS;
    }
    fd->cmd = cmd;
}

gboolean
waits_for_ack(const eglink_cmd_t *cmd)
{
    return cmd && !cmd->ack_frame;
}

/* The VRCI a VRAO from this controller acknowledges. Its own BU's first;
 * while that is not known from an acknowledgement, the BU of the channel
 * waiting longest for this Command ID, and the controller joins that BU. */
eglink_cmd_t *
vrci_acknowledged(eglink_ctrl_t *ctrl, guint16 command_id)
{
    eglink_cmd_t *cmd = ctrl->bu ? find_command(&ctrl->bu->s, command_id) : NULL;
    eglink_cmd_t *best = NULL;
    eglink_bu_t *bu, *best_bu = NULL;

    if (ctrl->joined_by_ack || waits_for_ack(cmd))
        return cmd;
    for (bu = ctrl->chan->bus; bu; bu = bu->next) {
        eglink_cmd_t *c = find_command(&bu->s, command_id);
        if (waits_for_ack(c) && (!best || c->first_frame < best->first_frame)) {
            best = c;
            best_bu = bu;
        }
    }
    if (!best)
        return cmd;
    ctrl->bu = best_bu;
    ctrl->joined_by_ack = TRUE;
    return best;
}

/* The VRCO a VRAI from this BU acknowledges: from a controller joined to it
 * first; else the one of the channel waiting longest for this Command ID,
 * whose BU is not known from an acknowledgement yet: it joins this BU. */
eglink_cmd_t *
vrco_acknowledged(eglink_bu_t *bu, guint16 command_id)
{
    eglink_ctrl_t *ctrl, *best_ctrl = NULL, *mine_ctrl = NULL;
    eglink_cmd_t *best = NULL, *mine = NULL;

    for (ctrl = bu->chan->ctrls; ctrl; ctrl = ctrl->next) {
        eglink_cmd_t *c;
        if (ctrl->bu != bu)
            continue;
        c = find_command(&ctrl->s, command_id);
        if (c && (!mine || c->first_frame > mine->first_frame)) {
            mine = c;
            mine_ctrl = ctrl;
        }
    }
    if (waits_for_ack(mine)) {
        mine_ctrl->joined_by_ack = TRUE;    /* (evidence now, not only being alone) */
        return mine;
    }
    for (ctrl = bu->chan->ctrls; ctrl; ctrl = ctrl->next) {
        eglink_cmd_t *c;
        if (ctrl->joined_by_ack)
            continue;
        c = find_command(&ctrl->s, command_id);
        if (waits_for_ack(c) && (!best || c->first_frame < best->first_frame)) {
            best = c;
            best_ctrl = ctrl;
        }
    }
    if (!best)
        return mine;
    best_ctrl->bu = bu;
    best_ctrl->joined_by_ack = TRUE;
    return best;
}

void
track_ack(eglink_cmd_t *cmd, eglink_frame_t *fd, packet_info *pinfo, int dir, guint16 command_id)
{
    gint64 age;

    if (!cmd) {
        add_finding(fd, FND_UNKNOWN_ACK, 0, command_id, 0);
        return;
    }
    fd->cmd = cmd;
    age = ns_between(&pinfo->abs_ts, &cmd->first_ts);
    /* (after a clock step the age counts from the step: no acknowledgement time) */
    if (!cmd->clock_step) {
        fd->delta_ns = age;
        fd->flags |= FF_DELTA;
    }
    if (!cmd->ack_frame) {
        cmd->ack_frame = pinfo->num;
        fd->flags |= FF_FIRST_ACK;
        if (age > ack_timeout_ns(dir)) {
            add_finding(fd, FND_LATE_ACK, cmd->first_frame, command_id, age);
            /* The acknowledgement is the first packet after the deadline:
             * the deadline was seen passing here. */
            if (!cmd->failed) {
                cmd->failed = TRUE;
                cmd->deadline_frame = pinfo->num;
            }
        }
    }
}

/* The acknowledgement of the frame being analysed that waits, in its
 * stored record, for its controller to turn up with a BU. */
eglink_orphan_ack_t *eglink_orphan_pending;

/* A VRAO a controller on a port of its own sent for a command not seen:
 * kept, with its record, until the controller turns up with a BU. */
void
remember_orphan_ack(eglink_ctrl_t *ctrl, packet_info *pinfo, guint16 command_id)
{
    eglink_orphan_ack_t *o;

    if (ctrl->n_orphan_acks >= EGLINK_ORPHAN_ACKS)
        return;
    o = &ctrl->orphan_acks[ctrl->n_orphan_acks++];
    o->fd = NULL;
    o->ts = pinfo->abs_ts;
    o->frame = pinfo->num;
    o->command_id = command_id;
    eglink_orphan_pending = o;
}

/* The controller turned up with a BU: the VRAOs it sent before, on a port
 * of its own, acknowledge that BU's VRCIs still waiting (in time); their
 * records say so from the second pass on. */
void
match_orphan_acks(eglink_ctrl_t *ctrl)
{
    guint i;

    for (i = 0; i < ctrl->n_orphan_acks; i++) {
        eglink_orphan_ack_t *o = &ctrl->orphan_acks[i];
        eglink_cmd_t *cmd = vrci_acknowledged(ctrl, o->command_id);
        eglink_finding_t **f;
        gint64 age;

        if (!o->fd || !waits_for_ack(cmd) || cmd->failed || cmd->first_frame > o->frame)
            continue;
        age = ns_between(&o->ts, &cmd->first_ts);
        if (age > ack_timeout_ns(EGLINK_DIR_IN))
            continue;
        cmd->ack_frame = o->frame;
        ctrl->joined_by_ack = TRUE;
        o->fd->cmd = cmd;
        o->fd->flags |= FF_FIRST_ACK;
        if (!cmd->clock_step) {
            o->fd->delta_ns = age;
            o->fd->flags |= FF_DELTA;
        }
        for (f = &o->fd->findings; *f; f = &(*f)->next) {
            if ((*f)->kind == FND_UNKNOWN_ACK) {
                *f = (*f)->next;
                break;
            }
        }
    }
    ctrl->n_orphan_acks = 0;
}

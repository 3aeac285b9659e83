/* eglink-stats.c
 * Statistics > EG-Link (tshark -z eglink,stat): per base unit, the packets
 * by type with the VRPI/VRPO intervals (the maximum is the longest gap) and
 * the command retransmissions, lost, repeated and invalid packets, commands
 * in both directions (acknowledged with their delay, failed), VRPO bursts,
 * and the time each BU spent in each state. Fed by the "eglink" tap of
 * eglink-analysis.c. Only the public stats_tree API (epan/stats_tree.h).
 * Its twin for the Lua EG-Link: lua/vrshark/eglink_stats.luam.
 *
 * How it reads in the GUI and in tshark alike:
 * - Wireshark's Statistics dialog (seen on 4.0; later versions have the
 *   same code) sorts every level of the
 *   tree by name, descending, until a column header is clicked, whatever
 *   the tree asks for; rows flagged ST_FLG_SORT_TOP stay above the others.
 *   The tree is registered to sort the same way (ST_SORT_COL_NAME and
 *   ST_FLG_SORT_DESC in the flags of stats_tree_register_plugin, which
 *   Wireshark keeps as the tree's default), so tshark prints what the
 *   dialog shows, and the labels are chosen so that this order reads
 *   right: the base units and each BU's packets first (SORT_TOP), packet
 *   types VRPO, VRPI, VRCO, VRCI, VRAO, VRAI, then repeated, lost and
 *   invalid packets; the commands; failures before acknowledgements; BU
 *   states by their code, Armed and Disarmed first, then the states with
 *   the relays open.
 * - Every row's Percent is a part of its parent: packet types of the BU's
 *   packets, acknowledged of the commands. The periods a BU spent in each
 *   state are in their own top-level tree ("BU state periods (length in
 *   ms)"): Count is the number of periods that ended in the capture,
 *   Average, Min and Max their length in ms, like every time in the tree
 *   (no milliseconds in Count).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-analysis.h"
#include "eglink-compat.h"

#include <stdio.h>
#include <epan/stats_tree.h>
#include <epan/stat_tap_ui.h>
#include <epan/tap.h>

#define ST_ROOT_NAME "EG-Link base units"
#define ST_TIME_NAME "BU state periods (length in ms)"

static const char *const type_names[] = { "VRPI", "VRPO", "VRCI", "VRCO", "VRAI", "VRAO" };

const char *
eglink_bu_state_name(guint8 state)
{
    return val_to_str_const(state, eglink_bu_state_vals, "Unknown");
}

static int
ms_of(gint64 ns)
{
    return (int)((ns + 500000) / 1000000);
}

static void
eglink_stats_init(stats_tree *st)
{
    stats_tree_create_node(st, ST_ROOT_NAME, 0, STAT_DT_INT, TRUE);
}

/* Keeps a row above its siblings. A reset of the tree clears the flags of
 * its rows, so they are set again whenever the row counts. */
static void
keep_on_top(stats_tree *st, const char *name, int parent_id, gboolean with_children)
{
    stats_tree_manip_node_int(MN_SET_FLAGS, st, name, parent_id, with_children, ST_FLG_SORT_TOP);
}

/* Commands of one direction: new ones counted on the node itself. */
static void
command_stats(stats_tree *st, int bu_node, const char *name, const eglink_tap_info_t *t,
              gboolean command, gboolean ack, int dir)
{
    int node, acked;

    if (!(command && t->new_command) && !(ack && t->first_ack) && !t->failed[dir])
        return;
    node = increase_stat_node(st, name, bu_node, TRUE, command && t->new_command ? 1 : 0);
    acked = increase_stat_node(st, "Acknowledged", node, TRUE, ack && t->first_ack ? 1 : 0);
    increase_stat_node(st, "Failed (not acknowledged in time)", node, FALSE, (int)t->failed[dir]);
    if (ack && t->first_ack)
        avg_stat_node_add_value_int(st, "Acknowledgement time (ms)", acked, FALSE, ms_of(t->ack_ns));
}

/* One period the BU spent in a state, ended by this VRPI (the first with
 * another state): a sample of the state's row (Count: periods,
 * Average/Min/Max: their length in ms), as Wireshark's own trees show
 * times. A period still running at the end of the capture has no end, and
 * is not counted. */
static void
state_time_stats(stats_tree *st, const eglink_tap_info_t *t)
{
    char state[64];
    int root, bu;

    /* "0x11 Armed": by code, as the dialog sorts them. */
    snprintf(state, sizeof state, "0x%02x %s", t->prev_state, eglink_bu_state_name(t->prev_state));
    root = tick_stat_node(st, ST_TIME_NAME, 0, TRUE);
    bu = tick_stat_node(st, t->bu_name, root, TRUE);
    avg_stat_node_add_value_int(st, state, bu, FALSE, ms_of(t->state_ns));
}

static tap_packet_status
eglink_stats_packet(stats_tree *st, packet_info *pinfo _U_, epan_dissect_t *edt _U_,
                    const void *p, tap_flags_t flags _U_)
{
    const eglink_tap_info_t *t = (const eglink_tap_info_t *)p;
    int root, bu_node, node, type_node, i;

    root = tick_stat_node(st, ST_ROOT_NAME, 0, TRUE);
    keep_on_top(st, ST_ROOT_NAME, 0, TRUE);
    bu_node = tick_stat_node(st, t->bu_name, root, TRUE);
    if (t->is_bu)
        keep_on_top(st, t->bu_name, root, TRUE);

    /* The fixed rows first, so that every BU lists them all. */
    node = increase_stat_node(st, "Packets", bu_node, TRUE, 1);
    keep_on_top(st, "Packets", bu_node, TRUE);
    for (i = 0; i < (int)G_N_ELEMENTS(type_names); i++) {
        type_node = increase_stat_node(st, type_names[i], node, TRUE, (int)t->type == i ? 1 : 0);
        if ((int)t->type != i)
            continue;
        if (t->has_interval)
            avg_stat_node_add_value_int(st, "Interval (ms)", type_node, FALSE, ms_of(t->interval_ns));
        if (t->retransmission)
            increase_stat_node(st, "Retransmissions", type_node, FALSE, 1);
    }
    increase_stat_node(st, "Repeated", node, FALSE, t->repeated ? 1 : 0);
    increase_stat_node(st, "Lost", node, FALSE, (int)t->lost);
    increase_stat_node(st, "Invalid (CRC or size, not analysed)", node, FALSE, t->invalid ? 1 : 0);

    command_stats(st, bu_node, "VRCI commands (BU to controller)", t,
                  t->type == EGLINK_TYPE_VRCI, t->type == EGLINK_TYPE_VRAO, EGLINK_DIR_IN);
    command_stats(st, bu_node, "VRCO commands (controller to BU)", t,
                  t->type == EGLINK_TYPE_VRCO, t->type == EGLINK_TYPE_VRAI, EGLINK_DIR_OUT);

    if (t->burst_complete || t->burst_incomplete) {
        node = increase_stat_node(st, "Split VRPO bursts", bu_node, TRUE,
                                  (t->burst_complete ? 1 : 0) + (t->burst_incomplete ? 1 : 0));
        increase_stat_node(st, "Reassembled", node, FALSE, t->burst_complete ? 1 : 0);
        increase_stat_node(st, "Incomplete", node, FALSE, t->burst_incomplete ? 1 : 0);
    }

    if (t->has_state_period)
        state_time_stats(st, t);
    return TAP_PACKET_REDRAW;
}

/* tshark -z eglink,stat[,FILTER]: stats_tree names its command line
 * "<abbr>,tree"; the "stat" spelling hands the same request, with its
 * filter, to that one (tshark starts every requested statistic in turn,
 * including one requested while it does so). */
#define EGLINK_STAT_CLI "eglink,stat"
#define EGLINK_TREE_CLI "eglink,tree"

static EGLINK_STAT_INIT_RET
eglink_stat_init(const char *opt_arg, void *userdata _U_)
{
    char *tree_arg = g_strconcat(EGLINK_TREE_CLI, opt_arg + strlen(EGLINK_STAT_CLI), NULL);
    gboolean ok = process_stat_cmd_arg(tree_arg);

    g_free(tree_arg);
    EGLINK_STAT_INIT_RETURN(ok);
}

void
eglink_stats_register(void)
{
    static stat_tap_ui stat_ui = {
        REGISTER_STAT_GROUP_GENERIC, NULL, EGLINK_STAT_CLI, eglink_stat_init, 0, NULL
    };

    stats_tree_register_plugin("eglink", "eglink", "EG-Link",
                               (ST_SORT_COL_NAME << ST_FLG_SRTCOL_SHIFT) | ST_FLG_SORT_DESC,
                               eglink_stats_packet, eglink_stats_init, NULL);
    register_stat_tap_ui(&stat_ui, NULL);
}

/* eglink-stats.c
 * Statistics > EG-Link (tshark -z eglink,stat): per base unit, the packets
 * by type, lost and repeated packets, VRPI/VRPO intervals (the maximum is
 * the longest gap), commands in both directions with their retransmissions,
 * failures and acknowledgement times, VRPO bursts, and the time the BU spent
 * in each state. Fed by the "eglink" tap of eglink-analysis.c.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-analysis.h"
#include "eglink-compat.h"

#include <stdio.h>
#include <epan/stats_tree.h>
#include <epan/stats_tree_priv.h>
#include <epan/stat_tap_ui.h>
#include <epan/tap.h>
#include <wsutil/report_message.h>

#define ST_ROOT_NAME "EG-Link base units"

static int st_node_root = -1;

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
    st_node_root = stats_tree_create_node(st, ST_ROOT_NAME, 0, STAT_DT_INT, TRUE);
}

/* Commands of one direction: new ones counted on the parent. */
static void
command_stats(stats_tree *st, int bu_node, const char *name, const eglink_tap_info_t *t,
              gboolean command, gboolean ack, int dir)
{
    int node;

    if (!command && !ack && !t->failed[dir])
        return;
    node = increase_stat_node(st, name, bu_node, TRUE, command && t->new_command ? 1 : 0);
    increase_stat_node(st, "Retransmissions", node, FALSE, command && t->retransmission ? 1 : 0);
    increase_stat_node(st, "Acknowledged", node, FALSE, ack && t->first_ack ? 1 : 0);
    increase_stat_node(st, "Failed (not acknowledged in time)", node, FALSE, (int)t->failed[dir]);
    if (ack && t->first_ack)
        avg_stat_node_add_value_int(st, "Acknowledgement time (ms)", node, FALSE, ms_of(t->ack_ns));
}

static tap_packet_status
eglink_stats_packet(stats_tree *st, packet_info *pinfo _U_, epan_dissect_t *edt _U_,
                    const void *p, tap_flags_t flags _U_)
{
    const eglink_tap_info_t *t = (const eglink_tap_info_t *)p;
    int bu_node, node, i;

    tick_stat_node(st, ST_ROOT_NAME, 0, TRUE);
    bu_node = tick_stat_node(st, t->bu_name, st_node_root, TRUE);

    /* The fixed rows first, so that every BU lists them in the same order. */
    node = increase_stat_node(st, "Packets", bu_node, TRUE, 1);
    for (i = 0; i < (int)G_N_ELEMENTS(type_names); i++)
        increase_stat_node(st, type_names[i], node, FALSE, (int)t->type == i ? 1 : 0);
    increase_stat_node(st, "Invalid (CRC or size, not analysed)", bu_node, FALSE, t->invalid ? 1 : 0);
    increase_stat_node(st, "Lost", bu_node, FALSE, (int)t->lost);
    increase_stat_node(st, "Repeated", bu_node, FALSE, t->repeated ? 1 : 0);

    if (t->has_interval)
        avg_stat_node_add_value_int(st, t->type == EGLINK_TYPE_VRPI ? "VRPI interval (ms)"
                                        : "VRPO interval (ms)", bu_node, FALSE, ms_of(t->interval_ns));

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

    if (t->has_state_time) {
        int ms = ms_of(t->state_ns);
        char name[48];

        snprintf(name, sizeof name, "%s (0x%02x)", eglink_bu_state_name(t->prev_state), t->prev_state);
        node = increase_stat_node(st, "Time in BU state (ms)", bu_node, TRUE, ms);
        increase_stat_node(st, name, node, FALSE, ms);
    }
    return TAP_PACKET_REDRAW;
}

/* tshark -z eglink,stat[,FILTER]: the stats tree registered below, printed
 * as tshark prints "-z eglink,tree" (which works too). stats_tree names its
 * command "<abbr>,tree", so the "stat" spelling gets its own, small command
 * line entry doing what tshark's tap-stats_tree.c does. */
#define EGLINK_STAT_CLI "eglink,stat"

static void
eglink_stat_draw(void *p)
{
    stats_tree *st = (stats_tree *)p;
    GString *s = stats_tree_format_as_str(st, ST_FORMAT_PLAIN, stats_tree_get_default_sort_col(st),
                                          stats_tree_is_default_sort_DESC(st));

    printf("%s", s->str);
    g_string_free(s, TRUE);
}

static void
eglink_stat_free(void *p)
{
    stats_tree_free((stats_tree *)p);
}

/* The callback returns bool from Wireshark 4.6 on, nothing before. */
#if EGLINK_WS_AT_LEAST(4, 6)
#define EGLINK_STAT_INIT_RET bool
#define EGLINK_STAT_INIT_RETURN(ok) return (ok)
#else
#define EGLINK_STAT_INIT_RET void
#define EGLINK_STAT_INIT_RETURN(ok) do { (void)(ok); return; } while (0)
#endif

static EGLINK_STAT_INIT_RET
eglink_stat_init(const char *opt_arg, void *userdata _U_)
{
    stats_tree_cfg *cfg = stats_tree_get_cfg_by_abbr("eglink");
    const char *filter = NULL;
    stats_tree *st;
    GString *error;

    if (cfg == NULL) {
        report_failure("eglink statistics are not registered");
        EGLINK_STAT_INIT_RETURN(false);
    }
    if (strncmp(opt_arg, EGLINK_STAT_CLI ",", strlen(EGLINK_STAT_CLI ",")) == 0)
        filter = opt_arg + strlen(EGLINK_STAT_CLI ",");
    st = stats_tree_new(cfg, NULL, filter);
    error = register_tap_listener(cfg->tapname, st, st->filter, cfg->flags, stats_tree_reset,
                                  stats_tree_packet, eglink_stat_draw, eglink_stat_free);
    if (error) {
        report_failure("-z " EGLINK_STAT_CLI ": %s", error->str);
        g_string_free(error, TRUE);
        stats_tree_free(st);
        EGLINK_STAT_INIT_RETURN(false);
    }
    if (cfg->init)
        cfg->init(st);
    EGLINK_STAT_INIT_RETURN(true);
}

void
eglink_stats_register(void)
{
    static stat_tap_ui stat_ui = {
        REGISTER_STAT_GROUP_GENERIC, NULL, EGLINK_STAT_CLI, eglink_stat_init, 0, NULL
    };

    stats_tree_register_plugin("eglink", "eglink", "EG-Link", 0,
                               eglink_stats_packet, eglink_stats_init, NULL);
    register_stat_tap_ui(&stat_ui, NULL);
}

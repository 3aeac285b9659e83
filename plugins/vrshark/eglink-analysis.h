/* eglink-analysis.h
 * What the EG-Link conversation analysis hands to its statistics tree
 * (eglink-stats.c) through the "eglink" tap, one record per analysed packet.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef EGLINK_ANALYSIS_H
#define EGLINK_ANALYSIS_H

#include "packet-eglink.h"

/* Commands in each direction: VRCI (BU to controller, acknowledged by VRAO)
 * and VRCO (controller to BU, acknowledged by VRAI). */
enum { EGLINK_DIR_IN = 0, EGLINK_DIR_OUT = 1 };

typedef struct {
    const char *bu_name;        /* "BU 0x1001 (10.0.0.1)", or "Controller 10.0.0.11 (BU not known)" */
    gboolean is_bu;             /* bu_name names a BU */
    eglink_type_t type;
    gboolean invalid;           /* CRC or size check failed: not analysed */
    gboolean repeated;          /* serial already seen: not analysed */
    guint lost;                 /* packets lost just before this one */

    gboolean has_interval;      /* VRPI/VRPO: time since the previous one */
    gint64 interval_ns;

    gboolean new_command;       /* first transmission of a VRCI/VRCO */
    gboolean retransmission;    /* a VRCI/VRCO retransmission */
    gboolean first_ack;         /* first VRAO/VRAI of its command */
    gint64 ack_ns;              /* ... and its delay after the first transmission */
    guint failed[2];            /* commands (per EGLINK_DIR_*) that failed at this packet */

    gboolean has_state_period;  /* VRPI with a new BU state: the period in prev_state ended */
    guint8 prev_state;
    gint64 state_ns;            /* ... its length, from the VRPI that first reported it */

    gboolean burst_complete;    /* a split VRPO burst ended complete here */
    gboolean burst_incomplete;  /* a split VRPO burst ended incomplete here */
} eglink_tap_info_t;

/* eglink-stats.c */
void eglink_stats_register(void);
const char *eglink_bu_state_name(guint8 state);

#endif /* EGLINK_ANALYSIS_H */

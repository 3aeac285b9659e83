/* vrshark-columns.h
 * Column text of the Lua decoders, written in C while a front end calls
 * them (vrshark-columns.c).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef VRSHARK_COLUMNS_H
#define VRSHARK_COLUMNS_H

#include <epan/packet.h>

/* The frame whose columns the Lua column writers fill, from here until
 * vrshark_columns_leave(): a front end brackets each call of a Lua decoder
 * with the two (nested calls restore the outer frame). */
packet_info *vrshark_columns_enter(packet_info *pinfo);
void vrshark_columns_leave(packet_info *outer);
/* That frame, or NULL outside a decoder call. */
packet_info *vrshark_columns_pinfo(void);

/* Tells the Lua side where this plugin is (environment variable
 * VRSHARK_FRONTENDS_LIB, its path), so that lua/vrshark/frontends.luam can
 * take the writers with package.loadlib(). Called at registration. */
void vrshark_columns_register(void);

/* The clock of the Lua side (vrshark-columns.c): the earliest deadline it
 * armed (absolute seconds; infinity: none) and the frames it marked as
 * carrying a finding (NULL or empty: none). Reset when a file starts. */
extern double vrshark_clock_due;
extern GHashTable *vrshark_clock_marks;
void vrshark_clock_reset(void);

/* Whether a front end calls the clock for this frame: on a first pass, its
 * time past the earliest deadline; on a later pass, a frame marked. One
 * comparison on healthy traffic (no deadline passed, no frame marked). */
static inline gboolean
vrshark_clock_wanted(packet_info *pinfo)
{
    if (!pinfo->fd->visited)
        return nstime_to_sec(&pinfo->abs_ts) > vrshark_clock_due;
    return vrshark_clock_marks && g_hash_table_size(vrshark_clock_marks) &&
           g_hash_table_contains(vrshark_clock_marks, GUINT_TO_POINTER(pinfo->num));
}

#endif /* VRSHARK_COLUMNS_H */

/* vrshark-flags.h
 * The Lua side's state that the front ends read on every frame, set by the
 * Lua side the moment it changes (vrshark-flags.c).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef VRSHARK_FLAGS_H
#define VRSHARK_FLAGS_H

#include <glib.h>

/* VRSHARK_FLAG_PN_PENDING, VRSHARK_FLAG_PN_RESPONSE: TRUE until the Lua
 * side first sets them (without the functions bound it never does, and
 * the front ends then ask it about every frame it might want). */
extern gboolean vrshark_flag_pn_pending;
extern gboolean vrshark_flag_pn_response;

/* The listed servers' names (VRSHARK_MB_SERVER_PREFIX "ADDR:PORT" or
 * "ADDR"); NULL until the Lua side first says its list. */
extern GHashTable *vrshark_mb_servers;

/* How often the Lua side said the entries of VRSHARK_MB_HOOK_TABLE changed:
 * the front end reads them again when this moves; 0 until it first says
 * so (then they are read on every frame). */
extern guint vrshark_mb_hooks_changes;

#endif /* VRSHARK_FLAGS_H */

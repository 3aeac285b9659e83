/* vrshark-tcpends.h
 * The TCP segments that end a connection (FIN, RST), kept for the Lua
 * decoder of EC-Link over Modbus/TCP (vrshark-tcpends.c).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef VRSHARK_TCPENDS_H
#define VRSHARK_TCPENDS_H

#include <glib.h>

/* TRUE when a segment is kept that the Lua side has not taken yet. */
extern gboolean vrshark_tcp_ends_pending;

/* A new file: the segments kept are forgotten (the listener stays). */
void vrshark_tcp_ends_reset(void);

#endif /* VRSHARK_TCPENDS_H */

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

/* Tells the Lua side where this plugin is (environment variable
 * VRSHARK_FRONTENDS_LIB, its path), so that lua/vrshark/frontends.luam can
 * take the writers with package.loadlib(). Called at registration. */
void vrshark_columns_register(void);

#endif /* VRSHARK_COLUMNS_H */

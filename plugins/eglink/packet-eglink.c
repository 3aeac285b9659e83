/* packet-eglink.c
 * Placeholder: the EG-Link dissector is being written.
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <wireshark.h>
#include <epan/packet.h>

void proto_register_eglink(void);
void proto_reg_handoff_eglink(void);

static int proto_eglink = -1;

void proto_register_eglink(void)
{
    proto_eglink = proto_register_protocol("VisionRemote EG-Link", "EG-Link", "eglink");
}

void proto_reg_handoff_eglink(void)
{
}

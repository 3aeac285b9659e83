/* eglink-analysis.c
 * EG-Link conversation analysis (placeholder until it is written).
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "packet-eglink.h"

void eglink_analysis_register(int proto _U_, module_t *prefs _U_)
{
}

void eglink_analysis_dissect(tvbuff_t *tvb _U_, packet_info *pinfo _U_, proto_tree *eglink_tree _U_,
                             proto_item *eglink_item _U_, const eglink_info_t *info _U_)
{
}

/* vrshark-output.h
 * Does this process print only named fields? (vrshark-output.c)
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef VRSHARK_OUTPUT_H
#define VRSHARK_OUTPUT_H

#include <glib.h>

/* TRUE when this process is tshark with -T fields as its output format
 * (its command line read once); FALSE where the command line cannot be
 * read. */
gboolean vrshark_fields_only(void);

/* This process's -e values (tshark does not mark them referenced when its
 * tree is visible); empty where the command line cannot be read. */
const GPtrArray *vrshark_fields_named(void);

#endif /* VRSHARK_OUTPUT_H */

/* vrshark-output.h
 * Does this process print only named fields? (vrshark-output.c)
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef VRSHARK_OUTPUT_H
#define VRSHARK_OUTPUT_H

#include <glib.h>

/* TRUE when the command line argv (argv[0] the program) is tshark's with
 * -T fields as its output format; the values of its -e options are added
 * to names (copies, char *), when names is not NULL. */
gboolean vrshark_fields_only_args(int argc, char **argv, GPtrArray *names);

/* The same for this process (its command line read once); FALSE where the
 * command line cannot be read. */
gboolean vrshark_fields_only(void);

/* This process's -e values (tshark does not mark them referenced when its
 * tree is visible); empty where the command line cannot be read. */
const GPtrArray *vrshark_fields_named(void);

#endif /* VRSHARK_OUTPUT_H */

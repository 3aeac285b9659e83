/* vrshark-output.c
 * Does this process print only named fields? (tshark -T fields)
 *
 * tshark -T fields prints nothing of the protocol tree but the fields named
 * with -e (and the columns among them). Wireshark 4.4 and 4.6 dissect it on
 * an invisible tree with those fields referenced; 4.0 makes the tree
 * visible, as for -V, and marks nothing, so a dissector cannot tell it from
 * a packet's details. The Lua decoders behind the front ends
 * (vrshark-frontends.c, lua_view) add only the referenced fields when
 * nothing else of their tree can be seen; this tells them that a visible
 * tree is such a case, and which fields -e names.
 *
 * It reads the process's own command line (/proc/self/cmdline; elsewhere it
 * answers "no", and the tree is built whole as before) and walks it as
 * tshark's getopt() does: an option that takes a value takes the rest of
 * its word or the next word, so "-Y -T" or "-o x:-T" is no -T. Only a
 * program named tshark is read.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-compat.h"

#include <string.h>
#include <glib.h>

#include "vrshark-output.h"

/* tshark's short options that take a value (its OPTSTRING with the
 * capture and dissection options, Wireshark 4.0 to 4.6); the others
 * (-2, -D, -g, -h, -I, -l, -L, -n, -p, -P, -q, -Q, -v, -V, -x) take none. */
#define TSHARK_VALUE_OPTIONS "aAbBcCdeEfFGHijJKMNoOrRsStTuUwWXyYz"

static gboolean
takes_value(char c)
{
    return strchr(TSHARK_VALUE_OPTIONS, c) != NULL;
}

/* The answer for this process: parsed once. */
static gboolean parsed;
static gboolean fields_only;
static GPtrArray *named;    /* the -e values (char *, owned) */

/* TRUE when the command line argv (argv[0] the program) is tshark's with
 * -T fields as its output format; the values of its -e options are added
 * to names (copies). */
static gboolean
fields_only_args(int argc, char **argv, GPtrArray *names)
{
    const char *prog, *output = NULL;
    int i;

    if (argc < 1 || !argv[0])
        return FALSE;
    prog = strrchr(argv[0], '/');
    prog = prog ? prog + 1 : argv[0];
    if (strncmp(prog, "tshark", 6) != 0)
        return FALSE;
    for (i = 1; i < argc; i++) {
        const char *a = argv[i];
        size_t k;

        if (strcmp(a, "--") == 0)
            break;
        /* long options (--name=value) and words that are no options */
        if (a[0] != '-' || a[1] == '-' || a[1] == '\0')
            continue;
        for (k = 1; a[k]; k++) {
            const char *value;

            if (!takes_value(a[k]))
                continue;
            value = a[k + 1] ? a + k + 1 : (i + 1 < argc ? argv[++i] : NULL);
            if (a[k] == 'T')
                output = value;
            else if (a[k] == 'e' && value)
                g_ptr_array_add(names, g_strdup(value));
            break;
        }
    }
    return output && strcmp(output, "fields") == 0;
}

static void
parse_own_command_line(void)
{
    gchar *text = NULL;
    gsize len = 0;

    parsed = TRUE;
    named = g_ptr_array_new_with_free_func(g_free);
    if (g_file_get_contents("/proc/self/cmdline", &text, &len, NULL) && len > 0) {
        GPtrArray *args = g_ptr_array_new();
        gsize at = 0;

        /* NUL-separated words, the last one NUL-terminated */
        while (at < len) {
            g_ptr_array_add(args, text + at);
            at += strlen(text + at) + 1;
        }
        fields_only = fields_only_args((int)args->len, (char **)args->pdata, named);
        g_ptr_array_free(args, TRUE);
    }
    g_free(text);
}

gboolean
vrshark_fields_only(void)
{
    if (!parsed)
        parse_own_command_line();
    return fields_only;
}

const GPtrArray *
vrshark_fields_named(void)
{
    if (!parsed)
        parse_own_command_line();
    return named;
}

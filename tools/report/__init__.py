"""vrshark-report: what a capture holds, and its safety timeline, from tshark's fields.

rows.py runs tshark (one `-T fields` run per capture) and yields its rows;
catalog.py names the expert fields the report knows; model.py builds the
devices, the timeline and the plot series from the rows; text.py, jsonout.py,
junit.py and html.py write them; cli.py is the command.
"""

"""vrshark-report: what a capture holds, and its safety timeline, from tshark's fields.

rows.py runs tshark (one `-T fields` run per capture) and yields its rows;
catalog.py names the expert fields the report knows; model.py builds the
devices, the timeline and the plot series from the rows; held.py words what
a capture holds (cut frames, undecoded PROFINET) for the hints of expect.py
and the text; text.py, jsonout.py,
junit.py and html.py write them; cli.py is the command.
"""

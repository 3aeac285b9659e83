"""Capture generator: readable scenario code that writes captures/*.pcap.

Each scenario module in this package registers its captures with
@capture("name.pcap", "what it shows"); `tools/gen-captures` writes them all,
byte-identically on every run (fixed timestamps, no randomness without a seed).
"""

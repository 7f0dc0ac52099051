"""The benchmark layer behind ``lcpcli bench``: suites with known outcomes, peers, the runner.
"""

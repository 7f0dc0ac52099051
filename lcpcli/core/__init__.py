"""The core layer: the problem model, results and statuses, the certificate, errors.

Nothing here imports another lcpcli layer; everything else builds on it.
"""

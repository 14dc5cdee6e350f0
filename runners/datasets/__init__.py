"""Recorded datasets (``python -m runners.dataset``): the manifest and the verification report."""

"""The sweep's machinery (``python -m runners.sweep``): its size and progress, the summary at its end, resume, the
stop file and the lock, the worker processes and their leftovers, and Slurm."""

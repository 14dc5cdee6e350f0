"""Slurm sweeps (``hydra/launcher=slurm``) on clusters without job accounting.

Submitit learns the state of its Slurm jobs from ``sacct`` alone. A cluster without ``slurmdbd`` (small clusters,
and the one-node cluster of ``tests/test_slurm.py``) answers ``sacct`` with "Slurm accounting storage is
disabled": Submitit then logs three warnings per poll and, worse, never learns that a job died without writing its
result (cancelled with SIGKILL, out of memory, over its time limit, on a lost node), so the launching process
waited for it forever instead of reporting the lost episodes and the resume command.

:func:`use_squeue_without_sacct` gives Submitit a watcher that asks ``sacct`` once and, where it fails, asks
``squeue --states=all`` instead, which knows every job of the cluster, finished ones included for ``MinJobAge``
(300 s by default) after they end, in the same ``JobID|State|NodeList`` form.
"""

from __future__ import annotations

import shutil
import subprocess

from submitit.slurm import slurm as submitit_slurm

SACCT_COLUMNS = "JobID|State|NodeList"  # the header of sacct's answer, which Submitit's parser reads
# Submitit polls ever less often while a job runs, up to every ``delay_s`` (600 s); squeue forgets a finished job
# after MinJobAge (300 s by default), so without sacct it is asked at least once a minute
SQUEUE_DELAY_S = 60


class SqueueFallbackWatcher(submitit_slurm.SlurmInfoWatcher):
    """Submitit's Slurm watcher, asking ``squeue`` when ``sacct`` does not work (no job accounting)."""

    def __init__(self, delay_s: int = 600) -> None:
        super().__init__(delay_s=delay_s)
        self.sacct_works: bool | None = None  # None: not asked yet

    def _make_command(self) -> list[str] | None:
        command = super()._make_command()
        if command is None or self.sacct_works is not False:
            return command
        ids = [command[i + 1] for i, arg in enumerate(command) if arg == "-j"]
        # %i names array tasks as sacct does (12_3, or 12_[4-7] while pending); --states=all includes ended jobs
        return ["squeue", "--noheader", "--states=all", "--format=%i|%T|%N", f"--jobs={','.join(ids)}"]

    def update(self) -> None:
        if self.sacct_works is None:
            command = super()._make_command()
            if command is None:
                return
            # asked once, quietly: where it fails, every later poll would log the same warning three times
            try:
                self.sacct_works = subprocess.run(command, capture_output=True, timeout=60).returncode == 0
            except (OSError, subprocess.TimeoutExpired):
                self.sacct_works = False
            if not self.sacct_works:
                self._delay_s = min(self._delay_s, SQUEUE_DELAY_S)
        super().update()

    def read_info(self, string: bytes | str) -> dict[str, dict[str, str]]:
        if self.sacct_works is False:
            text = string.decode() if isinstance(string, bytes) else string
            string = f"{SACCT_COLUMNS}\n{text}"
        return super().read_info(string)


def use_squeue_without_sacct() -> None:
    """Make Submitit's Slurm jobs (in this process) use :class:`SqueueFallbackWatcher`. Jobs share one watcher,
    a class attribute of Submitit's ``SlurmJob``; replaced once, before any job is submitted."""
    if not isinstance(submitit_slurm.SlurmJob.watcher, SqueueFallbackWatcher):
        submitit_slurm.SlurmJob.watcher = SqueueFallbackWatcher(delay_s=600)


RUN_LOCALLY = ("run on this machine's cores with hydra/launcher=all_cores (the default), or launch from a node "
               "of the cluster")
SLURM_COMMANDS = ("sbatch", "srun", "squeue")  # submit, run the task, follow its state


def slurm_problem(timeout_s: float = 30.0, what: str = "hydra/launcher=slurm", instead: str = RUN_LOCALLY
                  ) -> str | None:
    """Why ``hydra/launcher=slurm`` cannot submit from this machine, in one line, or None: a Slurm command is
    missing (not a Slurm node: Submitit said "Could not detect srun", reported as a lost worker), or the
    controller does not answer ``sinfo`` (Slurm installed, no cluster configured or reachable: four raw sbatch
    errors, then the same line). Asked before any job is composed or submitted. ``what`` names the option that
    asked for Slurm, ``instead`` says how to run without it (``runners.tune --launcher slurm`` has its own)."""
    missing = [c for c in SLURM_COMMANDS if shutil.which(c) is None]
    if missing:
        return (f"{what}: Slurm's {', '.join(missing)} not found on PATH, so this machine cannot submit "
                f"to a cluster; {instead}")
    try:
        done = subprocess.run(["sinfo", "--noheader", "--format=%P"], capture_output=True, text=True,
                              timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return f"{what}: the Slurm controller did not answer sinfo in {timeout_s:g} s; {instead}"
    except OSError as err:
        return f"{what}: sinfo could not run ({err.strerror or err}); {instead}"
    if done.returncode != 0:
        first = next((line.strip() for line in done.stderr.splitlines() if line.strip()), f"exit {done.returncode}")
        first = first.removeprefix("sinfo: ")
        return f"{what}: Slurm does not answer (sinfo: {first[:160]}); {instead}"
    return None


def is_slurm_launcher(launcher_target: str) -> bool:
    """Whether a launcher's ``_target_`` is Submitit's Slurm launcher (``hydra/launcher=slurm`` or
    ``submitit_slurm``)."""
    return "SlurmLauncher" in launcher_target and "Local" not in launcher_target

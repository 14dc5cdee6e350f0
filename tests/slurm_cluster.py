"""A one-node Slurm cluster started on this machine for the tests that submit to Slurm (``tests/test_slurm.py``:
sweeps; ``tests/test_slurm_tune.py``: a study's workers), through the ``slurm`` fixture of ``tests/conftest.py``.

:func:`one_node_cluster` generates a munge key, ``slurm.conf`` and ``cgroup.conf`` into a temporary directory (one
node, this host, with the machine's CPUs; no cgroups, no accounting database; free ports), starts ``munged``,
``slurmctld`` and ``slurmd`` and waits for the node to be idle; every Slurm command is pointed at the configuration
by ``SLURM_CONF`` (:attr:`Cluster.env`). The daemons are stopped at the end, also when a test fails, and the
fixture checks that no process of the cluster is left.

Needs root and Debian's ``slurm-wlm`` and ``munge`` (``.ci/run`` installs them). Without them the tests skip with
the reason, except in CI (``CI=true``), where that is a failure: CI must show that they ran.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

DAEMONS = ("munged", "slurmctld", "slurmd")
COMMANDS = ("munge", "sinfo", "sbatch", "squeue", "scancel")
PARTITION = "fuzzynav"


def unavailable(reason: str) -> None:
    """Skip, or in CI fail: the CI output must show that the cluster tests ran."""
    if os.environ.get("CI") == "true":
        pytest.fail(f"CI=true but the Slurm test cannot run: {reason}", pytrace=False)
    pytest.skip(f"no Slurm cluster can be started here: {reason}")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(predicate: Callable[[], bool], timeout: float, step: float = 0.2) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(step)
    return predicate()


@dataclass
class Cluster:
    """A running one-node cluster: its directory, the environment that points Slurm commands at it, the daemons."""

    root: Path
    env: dict[str, str]
    node: str
    cpus: int
    version: str
    daemons: dict[str, subprocess.Popen] = field(default_factory=dict)

    def run(self, *args: str, check: bool = True) -> subprocess.CompletedProcess:
        return subprocess.run(list(args), env=self.env, capture_output=True, text=True, timeout=60, check=check)

    def describe(self) -> str:
        return f"{self.version}, one node ({self.node}, {self.cpus} CPUs)"

    def jobs(self) -> dict[str, str]:
        """Every job the controller knows (finished ones too, for MinJobAge): id -> state."""
        out = self.run("squeue", "--noheader", "--states=all", "--format=%i %T").stdout
        return dict(line.split() for line in out.splitlines() if line.strip())

    def idle(self) -> bool:
        """No job pending or running."""
        return not self.run("squeue", "--noheader", "--format=%i").stdout.strip()

    def logs(self, limit: int = 3000) -> str:
        """The end of every daemon's log, for a failure message."""
        files = sorted(self.root.glob("*.log"))
        return "\n".join(f"== {p.name}\n{p.read_text(errors='replace')[-limit:]}" for p in files)


def config_files(root: Path, node: str, hardware: str, ports: tuple[int, int]) -> tuple[str, str]:
    """slurm.conf and cgroup.conf of a one-node cluster in ``root``: ``hardware`` is ``slurmd -C``'s line for
    this machine (CPUs, sockets, cores, memory), so that slurmd registers the node as configured."""
    slurm = f"""\
ClusterName=fuzzynav-ci
SlurmctldHost={node}
SlurmctldPort={ports[0]}
SlurmdPort={ports[1]}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={root}/munge/munge.socket
StateSaveLocation={root}/state
SlurmdSpoolDir={root}/spool
SlurmctldPidFile={root}/slurmctld.pid
SlurmdPidFile={root}/slurmd.pid
SlurmctldLogFile={root}/slurmctld.log
SlurmdLogFile={root}/slurmd.log
# no cgroups (containers and CI machines often cannot delegate them): plain process tracking, no task binding
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
# no slurmdbd: sacct does not work here, as on small clusters (runners.sweeping.slurm asks squeue instead)
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
InactiveLimit=0
KillWait=30
MinJobAge=600
{hardware} NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName={PARTITION} Nodes={node} Default=YES MaxTime=INFINITE State=UP
"""
    return slurm, "CgroupPlugin=autodetect\nIgnoreSystemd=yes\n"


def cluster_processes(conf: Path) -> list[tuple[int, str]]:
    """Live processes started for this cluster: those given its SLURM_CONF (daemons, job steps, jobs) or naming its
    directory on their command line (munged)."""
    found = []
    marker = f"SLURM_CONF={conf}".encode()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if (entry / "stat").read_text().rsplit(")", 1)[1].split()[0] == "Z":
                continue
            cmdline = (entry / "cmdline").read_bytes()
            if marker in (entry / "environ").read_bytes().split(b"\0") or str(conf.parent).encode() in cmdline:
                found.append((int(entry.name), cmdline.replace(b"\0", b" ").decode(errors="replace")[:120]))
        except (OSError, IndexError):
            continue
    return found


def stop_cluster(cluster: Cluster) -> list[tuple[int, str]]:
    """Cancel every job, stop the daemons (SIGTERM, then SIGKILL), kill whatever of the cluster is left; returns
    what was left over after the daemons stopped (nothing should be)."""
    if "slurmctld" in cluster.daemons:
        with contextlib.suppress(Exception):
            cluster.run("scancel", "--full", "--user=root", check=False)
            wait_for(cluster.idle, 20)
    for name in reversed(list(cluster.daemons)):  # slurmd, slurmctld, then munged that they authenticate with
        proc = cluster.daemons[name]
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
    conf = Path(cluster.env["SLURM_CONF"])
    wait_for(lambda: not cluster_processes(conf), 10)
    left = cluster_processes(conf)
    for pid, _ in left:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
    return left


def one_node_cluster(tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest) -> Iterator[Cluster]:
    """A one-node Slurm cluster on this machine, as a fixture's generator (``tests/conftest.py``'s ``slurm``, one
    cluster per test module); stopped at the end, whatever happened."""
    missing = [name for name in (*DAEMONS, *COMMANDS) if shutil.which(name) is None]
    if missing:
        unavailable(f"{', '.join(missing)} not found (apt-get install slurm-wlm munge)")
    if os.geteuid() != 0:
        unavailable("slurmd must run as root to start jobs")
    tic = time.monotonic()
    # a short path: munge's socket path must fit a sockaddr_un (108 bytes)
    root = Path(tmp_path_factory.mktemp("slurm", numbered=True))
    for sub in ("munge", "state", "spool"):
        (root / sub).mkdir()
    (root / "munge").chmod(0o755)  # munged refuses a key or socket directory writable by others
    key = root / "munge" / "munge.key"
    key.write_bytes(os.urandom(1024))
    key.chmod(0o600)
    node = socket.gethostname().split(".")[0]
    hardware = subprocess.run(["slurmd", "-C"], capture_output=True, text=True, timeout=60).stdout.splitlines()
    hardware_line = next((line for line in hardware if line.startswith("NodeName=")), "")
    if not hardware_line:
        unavailable(f"slurmd -C did not describe this machine: {hardware!r}")
    hardware_line = re.sub(r"^NodeName=\S+", f"NodeName={node}", hardware_line)
    slurm_conf, cgroup_conf = config_files(root, node, hardware_line, (free_port(), free_port()))
    (root / "slurm.conf").write_text(slurm_conf)
    (root / "cgroup.conf").write_text(cgroup_conf)
    env = {**os.environ, "SLURM_CONF": str(root / "slurm.conf")}
    version = subprocess.run(["sinfo", "--version"], capture_output=True, text=True, env=env).stdout.strip()
    cpus = int(re.search(r"CPUs=(\d+)", hardware_line).group(1))  # type: ignore[union-attr]
    cluster = Cluster(root, env, node, cpus, version)

    def start(name: str, *args: str) -> None:
        with open(root / f"{name}.out.log", "w") as out:
            cluster.daemons[name] = subprocess.Popen([name, *args], env=env, stdout=out, stderr=subprocess.STDOUT,
                                                     stdin=subprocess.DEVNULL, start_new_session=True)

    try:
        start("munged", "--foreground", "--force", f"--socket={root}/munge/munge.socket", f"--key-file={key}",
              f"--log-file={root}/munged.log", f"--pid-file={root}/munge/munged.pid", f"--seed-file={root}/munge/seed")
        assert wait_for((root / "munge" / "munge.socket").exists, 30), cluster.logs()
        start("slurmctld", "-D", "-i")
        start("slurmd", "-D", "-N", node)
        for name, proc in cluster.daemons.items():
            assert proc.poll() is None, f"{name} exited with {proc.returncode}\n{cluster.logs()}"

        def node_idle() -> bool:
            out = cluster.run("sinfo", "--noheader", "--Node", "--format=%t", check=False).stdout.split()
            return out == ["idle"]

        assert wait_for(node_idle, 60, 0.5), f"the node did not become idle\n{cluster.logs()}"
        started = time.monotonic() - tic
        yield cluster
    finally:
        left = stop_cluster(cluster)
    reporter = request.config.pluginmanager.get_plugin("terminalreporter")
    capture = request.config.pluginmanager.get_plugin("capturemanager")
    if reporter is not None:  # a line in CI's output that says the cluster tests ran, and on what
        # (pytest captures a fixture's teardown output and drops it when the test passed: write around the capture)
        with capture.global_and_fixture_disabled() if capture is not None else contextlib.nullcontext():
            reporter.write_line(f"\nslurm: {version}, one node ({node}, {cpus} CPUs) started in {started:.0f} s; "
                                f"tests ran on it for {time.monotonic() - tic - started:.0f} s; daemons stopped")
    assert not left, f"processes of the cluster were left running (killed now): {left}"


def array_tasks(sweep_dir: Path) -> list[str]:
    """Slurm job ids of the sweep's jobs, from Submitit's folders: ``<array job>_<task>``."""
    return sorted(p.name for p in (sweep_dir / ".submitit").iterdir() if re.fullmatch(r"\d+_\d+", p.name))


def job_processes(task: str) -> list[int]:
    """The Python processes that run the array task ``task`` (``<array job>_<task>``): the job step that Submitit
    starts with srun, found by the job's environment."""
    array_job, task_id = task.split("_")
    wanted = {f"SLURM_ARRAY_JOB_ID={array_job}".encode(), f"SLURM_ARRAY_TASK_ID={task_id}".encode()}
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        with contextlib.suppress(OSError):
            argv = (entry / "cmdline").read_bytes().split(b"\0")
            if "python" in Path(argv[0].decode(errors="replace")).name and b"submitit.core._submit" in argv \
                    and wanted <= set((entry / "environ").read_bytes().split(b"\0")):
                found.append(int(entry.name))
    return found

"""A one-node Slurm cluster on localhost for the farm tests, from Debian's slurm-wlm and munge,
started and stopped by the test itself (docs/farm.md "Tested here"). Everything lives in one
temporary folder: a fresh munge key and socket, slurm.conf with free ports, state and spool
folders, logs. The daemons run as root (slurmd launches the jobs); job scripts inherit the test's
environment (sbatch --export=ALL, Slurm's default). The backfill scheduler passes every second
(bf_interval=1, Slurm's default 30): a job whose dependency is met starts within about a second, not
~3 s (measured: a chain of 3 two-task arrays and a merge job of `true` completes in 3.6 s, 11.8 s
with the default)."""
import getpass
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class SlurmCluster:
    def __init__(self, cpus=2):
        self.dir = Path(tempfile.mkdtemp(prefix="schnee_slurm_", dir="/tmp"))  # short: the munge socket path
        self.cpus = cpus
        self.env = dict(os.environ, SLURM_CONF=str(self.dir / "slurm.conf"))
        self._pids = []

    def _write_conf(self):
        host = socket.gethostname().split(".")[0]
        user = getpass.getuser()  # root in CI (as the chroot tests need); the daemons run as this user
        d = self.dir
        for sub in ("state", "spool", "log", "munge"):
            (d / sub).mkdir(mode=0o700, exist_ok=True)
        (d / "slurm.conf").write_text(f"""ClusterName=schneetest
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={_free_port()}
SlurmdPort={_free_port()}
AuthType=auth/munge
AuthInfo=socket={d}/munge/munge.socket
CredType=cred/munge
SlurmUser={user}
SlurmdUser={user}
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/slurmd.pid
SlurmctldLogFile={d}/log/slurmctld.log
SlurmdLogFile={d}/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
JobRequeue=1
MinJobAge=600
KillWait=5
SchedulerType=sched/backfill
SchedulerParameters=bf_interval=1
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
NodeName={host} NodeAddr=127.0.0.1 CPUs={self.cpus} State=UNKNOWN
PartitionName=schnee Nodes=ALL Default=YES MaxTime=INFINITE State=UP
""")

    def start(self):
        d = self.dir
        self._write_conf()
        key = d / "munge" / "munge.key"
        key.write_bytes(os.urandom(1024))
        key.chmod(0o600)
        subprocess.run(["munged", f"--socket={d}/munge/munge.socket", f"--key-file={key}",
                        f"--pid-file={d}/munge/munged.pid", f"--log-file={d}/munge/munged.log",
                        f"--seed-file={d}/munge/seed", "--force"], check=True, timeout=30)
        conf = str(d / "slurm.conf")
        subprocess.run(["slurmctld", "-f", conf, "-i"], check=True, env=self.env, timeout=30)
        subprocess.run(["slurmd", "-f", conf], check=True, env=self.env, timeout=30)
        end = time.monotonic() + 60
        while time.monotonic() < end:
            out = subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True, env=self.env).stdout
            if out.strip() == "idle":
                return self
            time.sleep(0.5)
        raise RuntimeError("the Slurm node never became idle:\n" + self.logs())

    def logs(self):
        out = []
        for p in sorted((self.dir / "log").glob("*.log")):
            out.append(f"--- {p.name}\n" + p.read_text(errors="replace")[-3000:])
        return "\n".join(out)

    def run(self, *cmd, check=True):
        return subprocess.run(list(cmd), capture_output=True, text=True, env=self.env, check=check, timeout=60)

    def job_state(self, job):
        out = self.run("scontrol", "-o", "show", "job", str(job), check=False).stdout
        states = [f.split("=", 1)[1] for f in out.split() if f.startswith("JobState=")]
        return states

    def stop(self):
        d = self.dir
        subprocess.run(["scancel", f"--user={getpass.getuser()}"], env=self.env, capture_output=True, timeout=30)
        time.sleep(1)
        for name in ("slurmd.pid", "slurmctld.pid", "munge/munged.pid"):
            try:
                pid = int((d / name).read_text().split()[0])
                os.kill(pid, signal.SIGTERM)
                for _ in range(100):
                    os.kill(pid, 0)
                    time.sleep(0.05)
                os.kill(pid, signal.SIGKILL)
            except (OSError, ValueError):
                pass
        shutil.rmtree(d, ignore_errors=True)

"""Landing trials at cluster scale: `deckwatch trials` split into shards (`--shard K/N`), each
shard a Ray task that runs the `deckwatch` binary on a worker, a lost task retried, progress
shown (shards done, approaches a minute, ETA), the shards' records merged (`deckwatch trials
merge`, the same report one process gives, bit for bit) and the safety case written: the report
(`report.jsonl`, `report.txt`) and a plot of each rule's unsafe-rate bound at the touchdowns
reached, over the zero-failure bound against the number of touchdowns (`bound.png`).

    python3 cluster/run_trials.py --deckwatch target/release/deckwatch --shards 16 --out runs/x \\
        -- --sea-states 3,4,5,6 --seeds 101,102 --headings-deg 0,110,160 --approaches 40 --rules deckwatch

Without `--address`, a local Ray cluster is started on this machine (`--workers` CPUs); with
`--address ray://HEAD:10001` (or `auto` inside a cluster) the tasks go to that cluster. The
binary is taken from `--deckwatch` on each worker (preinstalled at the same path), or shipped
with the job (`--ship`: Ray's `runtime_env` uploads the binary's folder; each worker runs its
copy). Needs the `ray` package (ci/peers.sh installs it) and matplotlib for the plot.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time


def die_with_parent():
    """In the shard's child, before exec: killed with its Ray worker. A worker that dies (a node
    lost, a worker killed) has its task retried elsewhere; a `deckwatch` left running would fly
    the same shard twice, on a core the retry needs."""
    if sys.platform.startswith("linux"):
        import ctypes
        import signal

        PR_SET_PDEATHSIG = 1
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


def parse():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--deckwatch", required=True, help="the deckwatch binary (on every worker, or shipped)")
    ap.add_argument("--shards", type=int, required=True, help="parts of the job list, one Ray task each")
    ap.add_argument("--out", required=True, help="folder for the shards' records and the report")
    ap.add_argument("--address", help="a running Ray cluster (ray://HOST:10001, or auto); default: start one here")
    ap.add_argument("--workers", type=int, default=os.cpu_count(), help="CPUs of the local cluster")
    ap.add_argument("--retries", type=int, default=2, help="times a lost or failed shard is run again")
    ap.add_argument("--ship", action="store_true", help="ship the binary's folder with the job")
    ap.add_argument("trials", nargs=argparse.REMAINDER, help="-- then `deckwatch trials` options")
    a = ap.parse_args()
    a.trials = [t for t in a.trials if t != "--"]
    if any(t in ("--shard", "--json", "--threads") for t in a.trials):
        ap.error("--shard, --json and --threads are the driver's to set")
    if a.shards < 1:
        ap.error("--shards must be at least 1")
    return a


def main():
    a = parse()
    import ray  # here: `--help` works without it

    binary = os.path.abspath(a.deckwatch)
    os.makedirs(a.out, exist_ok=True)
    runtime_env = None
    if a.ship:
        runtime_env = {"working_dir": os.path.dirname(binary)}
    if a.address:
        ray.init(address=a.address, runtime_env=runtime_env, log_to_driver=False)
    else:
        ray.init(num_cpus=a.workers, runtime_env=runtime_env, log_to_driver=False, include_dashboard=False)

    @ray.remote(num_cpus=1, max_retries=a.retries, retry_exceptions=True)
    def shard(k, n, binary_name, trials):
        # Shipped: the binary sits in the task's working folder.
        exe = os.path.join(os.getcwd(), binary_name) if a.ship else binary_name
        started = time.time()
        run = subprocess.run(
            [exe, "trials", *trials, "--json", "--threads", "1", "--shard", f"{k}/{n}"],
            capture_output=True, text=True, preexec_fn=die_with_parent,
        )
        if run.returncode != 0:
            raise RuntimeError(f"shard {k}/{n} failed ({run.returncode}): {run.stderr[-2000:]}")
        return k, run.stdout, time.time() - started

    name = os.path.basename(binary) if a.ship else binary
    pending = {shard.remote(k, a.shards, name, a.trials): k for k in range(1, a.shards + 1)}
    started = time.time()
    approaches = 0
    files = []
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        for ref in done:
            k, text, seconds = ray.get(ref)
            del pending[ref]
            path = os.path.join(a.out, f"shard-{k:04d}-of-{a.shards:04d}.jsonl")
            with open(path, "w") as f:
                f.write(text)
            files.append(path)
            approaches += sum(1 for line in text.splitlines() if line.startswith('{"approach"'))
            elapsed = time.time() - started
            finished = a.shards - len(pending)
            rate = approaches / elapsed * 60 if elapsed > 0 else 0.0
            eta = elapsed / finished * len(pending)
            print(
                f"shards {finished}/{a.shards}, {approaches} approach records, {rate:.0f} a minute, "
                f"ETA {eta:.0f} s (shard {k}: {seconds:.1f} s)",
                file=sys.stderr, flush=True,
            )
    ray.shutdown()

    files.sort()
    merged = subprocess.run([binary, "trials", "merge", "--json", *files], capture_output=True, text=True)
    if merged.returncode != 0:
        raise SystemExit(f"trials merge failed: {merged.stderr}")
    with open(os.path.join(a.out, "report.jsonl"), "w") as f:
        f.write(merged.stdout)
    table = subprocess.run([binary, "trials", "merge", *files], capture_output=True, text=True)
    with open(os.path.join(a.out, "report.txt"), "w") as f:
        f.write(table.stdout)
    print(table.stdout)
    plot(merged.stdout, os.path.join(a.out, "bound.png"))


def plot(report, path):
    """Each rule's unsafe-touchdown rate bound as deckwatch's merge reported it (the exact
    one-sided 95 % bound, `trials::stats`: not computed a second time here), at the number of
    touchdowns the campaign reached, over the zero-failure line 1 - 0.05^(1/n): how far a
    campaign of this size gets, and how many touchdowns a smaller bound needs."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("no matplotlib: no plot", file=sys.stderr)
        return
    totals = []
    for line in report.splitlines():
        v = json.loads(line)
        if v.get("sea_state") == "all" and "safety_case" in v:
            totals.append((v["rule"], v["summary"]["touchdowns"], v["summary"]["unsafe_touchdowns"],
                           v["safety_case"]["unsafe_rate_upper_95"]))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    n_max = max([t[1] for t in totals] + [1])
    xs = [round(10 ** (k / 20)) for k in range(0, 20 * (int(math.log10(max(n_max, 10) * 100)) + 1))]
    xs = sorted({x for x in xs if x >= 1})
    ax.plot(xs, [1 - 0.05 ** (1 / x) for x in xs], "k:", label="0 unsafe in n")
    for rule, n, k, bound in totals:
        if n > 0:
            ax.plot([n], [bound], "o", label=f"{rule}: {k} unsafe in {n}, bound {100 * bound:.3g} %")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("touchdowns")
    ax.set_ylabel("unsafe rate, exact 95 % upper bound")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"plot: {path}", file=sys.stderr)


if __name__ == "__main__":
    main()

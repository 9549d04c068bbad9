#!/usr/bin/env python3
"""Checks that a Kubernetes manifest runs a keyshape-lab corpus study as an Indexed Job
whose pods read their shard from JOB_COMPLETION_INDEX: completionMode Indexed, `kslab run
... --shard auto` (or --shard $(JOB_COMPLETION_INDEX)/N), KSLAB_SHARD_COUNT (or N) equal
to the Job's completions, and an --out folder per index. Used by the test
corpus::the_kubernetes_manifests_validate_and_run_an_indexed_job_reading_its_shard
(schema validity is kubernetes-validate's job). Needs PyYAML."""
import sys

import yaml


def fail(msg):
    print(f"{sys.argv[1]}: {msg}", file=sys.stderr)
    sys.exit(1)


docs = [d for d in yaml.safe_load_all(open(sys.argv[1])) if d]
jobs = [d for d in docs if d.get("kind") == "Job"]
if len(jobs) != 1:
    fail(f"expected one Job, found {len(jobs)}")
spec = jobs[0]["spec"]
if spec.get("completionMode") != "Indexed":
    fail("the Job is not Indexed (completionMode: Indexed)")
completions = spec.get("completions")
if not isinstance(completions, int) or completions < 1:
    fail("the Job needs completions >= 1")
containers = spec["template"]["spec"]["containers"]
runs = [c for c in containers if "run" in (c.get("args") or [])]
if len(runs) != 1:
    fail("expected one container running `kslab run`")
c = runs[0]
args = c["args"]
if "--shard" not in args:
    fail("the pod does not pass --shard")
shard = args[args.index("--shard") + 1]
env = {e["name"]: e.get("value") for e in c.get("env") or []}
if shard == "auto":
    if env.get("KSLAB_SHARD_COUNT") != str(completions):
        fail(f"KSLAB_SHARD_COUNT={env.get('KSLAB_SHARD_COUNT')} but completions={completions}")
elif shard != f"$(JOB_COMPLETION_INDEX)/{completions}":
    fail(f"--shard {shard} does not read JOB_COMPLETION_INDEX of {completions}")
if "--out" not in args or "$(JOB_COMPLETION_INDEX)" not in args[args.index("--out") + 1]:
    fail("each index needs its own --out folder (with $(JOB_COMPLETION_INDEX))")
print(f"ok: Indexed Job of {completions}, shard from JOB_COMPLETION_INDEX")

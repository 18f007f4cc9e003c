#!/bin/sh
# par.sh SPLIT TAG CANDS [MAPS] [angles]: two shards in parallel, then the merged summary
cd /work/main
export PYTHONPATH=python RAYON_NUM_THREADS=1
SHARD=0/2 python3 benches/r32/s8q/run.py "$@" &
SHARD=1/2 python3 benches/r32/s8q/run.py "$@" &
wait
SHARD=merge python3 benches/r32/s8q/run.py "$@"

#!/bin/bash
here=$(cd "$(dirname "$0")" && pwd)
# gwemopt 0.4.2, ZTF,DECam, as SkyPortal's combined plans call it (no --doIterativeTiling)
R=/work/wt/measure53/benchmarks/results/science/joint_plan/gwemopt
name=$1; map=$2
gps=$(/work/main/.venv/bin/python -c "
from mushrooms.scheduler_core import read_skymap
print('%.3f' % read_skymap('$map', nside=64).event_time.gps)")
mkdir -p $R/$name; cd $R/$name
args="--telescopes ZTF,DECam -e $map -o $R/$name/out --gpstime $gps --Tobs 0,1 --doTiles --tilesType moc --doSchedule --scheduleType greedy --timeallocationType powerlaw --filters g,r --exposuretimes 300,300 --doSingleExposure --doAlternatingFilters --nside 128 --airmass 2.5"
echo "$args" > args.txt; uptime > log.txt
start=$(date +%s)
OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 RAYON_NUM_THREADS=1 NUMBA_NUM_THREADS=1 MPLBACKEND=Agg PYTHONWARNINGS=ignore timeout 1200 nice -n 10 /work/gwemopt-venv/bin/python $here/launcher.py $args >> log.txt 2>&1
echo "rc $? wall $(( $(date +%s) - start )) s" >> log.txt; uptime >> log.txt

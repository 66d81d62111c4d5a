"""Side-by-side benchmark harness for the Exudyn peer of VALIDATION.md section E.

Benchmark-only: stdlib only, runnable with any python3. Exudyn and numpy live in a
separate virtualenv (bench/.venv-peer) and are NEVER a runtime dependency of the project.

    python3 bench/peer_exudyn.py                     # nel=4, h=2e-3, 3 repeats -> JSON
    python3 bench/peer_exudyn.py --ensure-venv       # create bench/.venv-peer first

The peer script (../shared/peers/exudyn_section_E.py, read-only) prints e.g.

    nel4_h0.002_sparse: setup 0.002s solve(med of 3) 0.937s  (0.0937 s per simulated s)  q0=['-20.000', '20.000', '-20.000']
      t=3.5  tip3=(6.11547, -4.15554)  w=(-0.13639 -0.05647 -0.00915) q=(-28.220 10.947 -21.960)
      t=5    tip3=(...)  w=(...) q=(...)
      t=10   tip3=(...)  w=(...) q=(...)
      max|w| per link = 0.14538 0.07779 0.02418 m

and writes $PEER_RESULTS_DIR/results/caseB_<tag>.json (tag = nel<N>_h<h>_<solver>).
NOTE: the printed "s per simulated s" is the median solver WALL time (perf_counter) / 10 s;
the JSON also holds the process CPU time (cpu_s, cpu_med), which is what
"cpu_s_per_sim_s" below reports (they agree to <1% on this single-threaded solve).
"""
import csv
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_DIR = os.path.dirname(BENCH_DIR)
PEER_SCRIPT = os.path.join(REPO_DIR, '..', 'shared', 'peers', 'exudyn_section_E.py')
REFERENCE_CSV = os.path.join(REPO_DIR, '..', 'shared', 'reference', 'section_E_reference_exudyn.csv')
PEER_VENV = os.path.join(BENCH_DIR, '.venv-peer')
# versions measured on 2 cores / Python 3.11.7 (pip wheels, manylinux x86_64)
PINNED = ('exudyn==1.13.6', 'numpy==2.4.6')
SIM_END_S = 10.0   # tEnd hard-coded in the peer script

_FLOAT = r'[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?'
_HEAD_RE = re.compile(r'^(?P<tag>\S+): setup (?P<setup>%s)s solve\(med of (?P<rep>\d+)\) (?P<solve>%s)s\s+'
                      r'\((?P<persim>%s) s per simulated s\)' % (_FLOAT, _FLOAT, _FLOAT))
_TIME_RE = re.compile(r'^\s*t=(?P<t>%s)\s+tip3=\((?P<x>%s), (?P<y>%s)\)\s+w=\((?P<w>[^)]*)\)\s+q=\((?P<q>[^)]*)\)'
                      % (_FLOAT, _FLOAT, _FLOAT))
_MAXW_RE = re.compile(r'^\s*max\|w\| per link = (?P<w>.*?) m\s*$')


def _venv_python(venv=None):
    venv = venv or PEER_VENV
    for rel in (('bin', 'python'), ('Scripts', 'python.exe')):
        p = os.path.join(venv, *rel)
        if os.path.exists(p):
            return p
    return None


def ensure_peer_venv(venv=None, base_python=None, pins=PINNED):
    """Create the benchmark-only venv and pip-install the pinned exudyn + numpy.
    Returns the venv's python path, or None (with a printed reason) on failure."""
    venv = venv or PEER_VENV
    py = _venv_python(venv)
    if py is None:
        r = subprocess.run([base_python or sys.executable, '-m', 'venv', venv])
        py = _venv_python(venv)
        if r.returncode != 0 or py is None:
            print('peer_exudyn: could not create venv %s' % venv)
            return None
    r = subprocess.run([py, '-m', 'pip', 'install', '-q', *pins])
    if r.returncode != 0:
        print('peer_exudyn: pip install %s failed (rc %d)' % (' '.join(pins), r.returncode))
        return None
    return py


def peer_runs(script, resolutions, duration):
    """Run ``script --peer --n-el N --h H --duration D`` in the peer venv for each
    (N, H) of ``resolutions``; {(N, H): the JSON it prints after "JSON"}, or None (and
    why, printed) when the venv is missing or a run fails."""
    py = _venv_python()
    if py is None:
        print("bench/.venv-peer is missing (python3 bench/peer_exudyn.py --ensure-venv)")
        return None
    out = {}
    for n_el, h in resolutions:
        r = subprocess.run([py, os.path.abspath(script), "--peer", "--n-el", str(n_el),
                            "--h", repr(h), "--duration", repr(duration)],
                           capture_output=True, text=True)
        line = next((x for x in r.stdout.splitlines() if x.startswith("JSON")), None)
        if line is None:
            print(f"Exudyn run {(n_el, h)} failed:", r.stdout[-2000:], r.stderr[-3000:])
            return None
        out[(n_el, h)] = json.loads(line[4:])
    return out


def _installed_versions(python):
    """exudyn/numpy versions from the venv's dist-info dirs (no import, no subprocess)."""
    out = {}
    prefix = os.path.dirname(os.path.dirname(python))
    for d in glob.glob(os.path.join(prefix, 'lib*', 'python*', 'site-packages', '*.dist-info')) + \
            glob.glob(os.path.join(prefix, 'Lib', 'site-packages', '*.dist-info')):
        name, _, ver = os.path.basename(d)[:-len('.dist-info')].partition('-')
        if name.lower() in ('exudyn', 'numpy'):
            out[name.lower()] = ver
    return out


def _floats(s):
    return [float(v) for v in re.findall(_FLOAT, s)]


def parse_peer_output(text):
    """Parse the peer's stdout. Returns a dict (possibly partial) or None if no header line."""
    res, tip3, w, q = {}, {}, {}, {}
    for line in text.splitlines():
        m = _HEAD_RE.match(line)
        if m:
            res.update(tag=m.group('tag'), setup_med_s=float(m.group('setup')),
                       repeats=int(m.group('rep')), solve_med_wall_s=float(m.group('solve')),
                       solve_wall_s_per_sim_s=float(m.group('persim')))
            mq = re.search(r'q0=\[(.*)\]', line)
            if mq:
                res['q0_deg'] = _floats(mq.group(1).replace("'", ''))
            continue
        m = _TIME_RE.match(line)
        if m:
            t = float(m.group('t'))
            tip3[t] = (float(m.group('x')), float(m.group('y')))
            w[t] = tuple(_floats(m.group('w')))
            q[t] = tuple(_floats(m.group('q')))
            continue
        m = _MAXW_RE.match(line)
        if m:
            res['max_abs_w_m'] = tuple(_floats(m.group('w')))
    if 'tag' not in res:
        return None
    res.update(tip3_xy_m=tip3, w_m=w, q_deg=q)
    return res


def _reference_tip3(times, path=None):
    """Tip of link 3 from the shared reference CSV (nearest row) at the given times, or {}."""
    path = path or REFERENCE_CSV
    if not os.path.exists(path):
        return {}
    rows = []
    with open(path) as f:
        for row in csv.reader(f):
            if row and not row[0].lstrip().startswith('#'):
                rows.append((float(row[0]), float(row[5]), float(row[6])))
    out = {}
    for t in times:
        r = min(rows, key=lambda r: abs(r[0] - t))
        if abs(r[0] - t) < 1e-6:
            out[t] = (r[1], r[2])
    return out


def run_peer(nel=4, h=2e-3, repeats=3, python=None, solver='sparse', timeout=1800, extra_args=()):
    """Run the Exudyn peer once (it does `repeats` solves internally, reports the median).

    Returns a dict with at least
      cpu_s_per_sim_s        median process CPU s of the solve / simulated s (from results JSON;
                             falls back to the printed wall-time figure)
      solve_wall_s_per_sim_s the printed figure (median solver wall time / 10 s)
      tip3_xy_m              {3.5: (x, y), 5.0: (x, y), 10.0: (x, y)}   [m]
      w_m, q_deg             {t: (link1, link2, link3)}  tip deflection [m], joint angle [deg]
      max_abs_w_m            (3 floats) [m]
      wall_s                 whole subprocess wall time (includes interpreter + import)
    or None (with a printed reason) if the peer script or venv is missing, or the run fails.
    """
    script = os.path.normpath(PEER_SCRIPT)
    if not os.path.exists(script):
        print('peer_exudyn: peer script not found at %s' % script)
        return None
    if python is None:
        python = _venv_python()
        if python is None:
            print('peer_exudyn: peer venv %s does not exist; call ensure_peer_venv() '
                  '(or run with --ensure-venv)' % PEER_VENV)
            return None
    elif not os.path.exists(python) and shutil.which(python) is None:
        print('peer_exudyn: python %s not found' % python)
        return None
    cmd = [python, script, '--nel', str(nel), '--h', repr(float(h)), '--solver', solver,
           '--repeats', str(int(repeats)), *extra_args]
    with tempfile.TemporaryDirectory(prefix='peer_exudyn_') as tmp:
        env = dict(os.environ, PEER_RESULTS_DIR=tmp)
        t0 = time.perf_counter()
        try:
            p = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            print('peer_exudyn: peer timed out after %ss: %s' % (timeout, ' '.join(cmd)))
            return None
        except OSError as e:
            print('peer_exudyn: could not start %s: %s' % (python, e))
            return None
        wall = time.perf_counter() - t0
        if p.returncode != 0:
            print('peer_exudyn: peer exited with %d\n%s' % (p.returncode, p.stderr[-2000:]))
            return None
        res = parse_peer_output(p.stdout)
        if res is None:
            print('peer_exudyn: could not parse peer output:\n%s' % p.stdout[-2000:])
            return None
        files = sorted(glob.glob(os.path.join(tmp, 'results', '*.json')))
        js = None
        if files:
            with open(files[0]) as f:
                js = json.load(f)
    res['cpu_s_per_sim_s'] = res['solve_wall_s_per_sim_s']
    res['cpu_source'] = 'printed wall time (results JSON missing)'
    if js is not None:
        sim_s = SIM_END_S
        if js.get('solve_per_simsec'):
            sim_s = js['solve_med'] / js['solve_per_simsec']
        res['cpu_s_per_sim_s'] = js['cpu_med'] / sim_s
        res['cpu_source'] = 'results JSON cpu_med (process_time)'
        res.update(cpu_s=js.get('cpu_s'), solve_wall_s=js.get('solve_s'), nODE2=js.get('nODE2'),
                   nAE=js.get('nAE'), results_file=os.path.basename(files[0]))
    # full-precision tip from the JSON samples when present (the print is rounded to 10 um)
    tipfull = {t: tuple(js['samples']['%g' % t]['tip3']) if js and '%g' % t in js.get('samples', {})
               else xy for t, xy in res['tip3_xy_m'].items()}
    ref = _reference_tip3(list(tipfull))
    if ref:
        res['tip3_err_vs_reference_mm'] = {
            t: 1e3 * ((x - ref[t][0]) ** 2 + (y - ref[t][1]) ** 2) ** 0.5
            for t, (x, y) in tipfull.items() if t in ref}
    res.update(nel=nel, h=h, solver=solver, wall_s=wall, command=' '.join(cmd),
               versions=_installed_versions(python), raw_stdout=p.stdout)
    return res


if __name__ == '__main__':
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--nel', type=int, default=4)
    ap.add_argument('--h', type=float, default=2e-3)
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--python', default=None, help='python with exudyn (default: bench/.venv-peer)')
    ap.add_argument('--ensure-venv', action='store_true', help='create bench/.venv-peer if needed')
    a = ap.parse_args()
    if a.ensure_venv and a.python is None and ensure_peer_venv() is None:
        sys.exit(1)
    r = run_peer(a.nel, a.h, a.repeats, python=a.python)
    if r is None:
        sys.exit(1)
    r.pop('raw_stdout', None)
    print(json.dumps(r, indent=1))

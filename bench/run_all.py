"""Run every benchmark script in bench/ (bench_*.py) in turn; `make bench` calls this."""
import runpy
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: arguments per script: the diagnosis benchmark's default (10 runs per case, the issue's
#: figure) takes hours on 2 cores; `make bench` runs one seed per case
ARGS = {"bench_diagnosis.py": ["--runs", "1"]}

if __name__ == "__main__":
    scripts = sorted(HERE.glob("bench_*.py"))
    for script in scripts:
        print(f"\n=== {script.name} ===", flush=True)
        sys.argv = [str(script), *ARGS.get(script.name, [])]
        try:
            runpy.run_path(str(script), run_name="__main__")
        except SystemExit as exc:   # a script ending with sys.exit(main()) must not end the loop
            if exc.code:
                raise

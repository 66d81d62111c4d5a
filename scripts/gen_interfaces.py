"""Build tf2_msgs and control_msgs into the venv from scripts/interfaces (issue 46).

Run by scripts/bootstrap.sh with the venv's python. It drives the rosidl generator wheels the
venv already has (adapter -> .idl, type_description -> .json with RIHS01 hashes, generator_c,
typesupport c/introspection_c/fastrtps_c, generator_py), compiles the output with the machine's
gcc/g++ and installs it the way the ros-* wheels lay out their own packages:
  .venv/lib/lib<pkg>__<part>.so            (found through the wheels' LD_LIBRARY_PATH hook)
  .venv/lib/python3.11/site-packages/<pkg> (the Python package and its C extensions)
  .venv/share/<pkg>/...                    (.msg/.idl/.json, ament index entries)
Build files stay in .venv/build-interfaces. Usage, with that venv's python:
  .venv/bin/python scripts/gen_interfaces.py [--venv DIR]
The generator classes are called directly: the `rosidl generate` CLI refuses to start here
(each generator wheel registers its entry points twice, egg-info and dist-info).
"""
import argparse
import concurrent.futures as cf
import contextlib
import io
import os
import pathlib
import shutil
import subprocess
import sys
import sysconfig
import time

HERE = pathlib.Path(__file__).resolve().parent
SOURCES = HERE / 'interfaces'
# package -> interface packages its definitions (and their action/service wrappers) use
PACKAGES = {
    'tf2_msgs': ['builtin_interfaces', 'geometry_msgs', 'std_msgs', 'action_msgs',
                 'unique_identifier_msgs', 'service_msgs'],
    'control_msgs': ['builtin_interfaces', 'geometry_msgs', 'std_msgs', 'trajectory_msgs',
                     'action_msgs', 'unique_identifier_msgs', 'service_msgs'],
}
TYPESUPPORTS = ['rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_introspection_c']
# library part -> folder its generated sources go to under .venv/build-interfaces
GEN_DIRS = {'rosidl_generator_c': 'c', 'rosidl_typesupport_c': 'ts_c',
            'rosidl_typesupport_introspection_c': 'introspection_c',
            'rosidl_typesupport_fastrtps_c': 'fastrtps_c'}


def log(msg):
    print(f'[gen_interfaces] {msg}', file=sys.stderr, flush=True)


def run(cmd):
    """Run a compiler command; raise with its output on failure."""
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f'{cmd[0]} failed:\n{" ".join(cmd)}\n{res.stderr[-4000:]}')


def interface_files(pkg):
    """(package folder, relative paths of every .msg/.srv/.action shipped for pkg)."""
    root = SOURCES / pkg
    files = [p for p in sorted(root.glob('*/*')) if p.suffix in ('.msg', '.srv', '.action')]
    return root, [p.relative_to(root) for p in files]


def to_idl(pkg, root, rel_files, out):
    """Translate .msg/.srv/.action to .idl; return '<out>:<rel>.idl' tuples."""
    from rosidl_adapter import convert_to_idl
    idl = []
    with contextlib.redirect_stdout(io.StringIO()):  # it prints every file it reads/writes
        for rel in rel_files:
            path = convert_to_idl(root, pkg, rel, out)
            idl.append(f'{out}:{path.relative_to(out)}')
    return idl


def generate(pkg, share, build):
    """Run every rosidl generator for pkg into build/<generator>/<pkg>; return the .idl
    tuples and the .json type descriptions (with the hashes)."""
    from rosidl_generator_c.cli import GenerateC
    from rosidl_generator_py.cli import GeneratePython
    from rosidl_generator_type_description.cli import HashTypeDescription
    from rosidl_typesupport_c.cli import GenerateCTypesupport
    from rosidl_typesupport_fastrtps_c.cli import GenerateFastRTPSCTypesupport
    from rosidl_typesupport_introspection_c.cli import GenerateIntrospectionCTypesupport

    root, rel = interface_files(pkg)
    idl = to_idl(pkg, root, rel, build / 'idl' / pkg)
    include = [str(share / dep) for dep in PACKAGES[pkg]]
    json_files = HashTypeDescription('type_description').generate_type_hashes(
        pkg, idl, include, output_path=build / 'json' / pkg)
    GenerateC('c').generate(pkg, idl, include, build / GEN_DIRS['rosidl_generator_c'] / pkg,
                            type_description_files=json_files)
    GenerateCTypesupport('c', typesupport_implementations=TYPESUPPORTS).generate(
        pkg, idl, include, build / GEN_DIRS['rosidl_typesupport_c'] / pkg)
    GenerateIntrospectionCTypesupport('introspection_c').generate(
        pkg, idl, include, build / GEN_DIRS['rosidl_typesupport_introspection_c'] / pkg)
    GenerateFastRTPSCTypesupport('fastrtps_c').generate(
        pkg, idl, include, build / GEN_DIRS['rosidl_typesupport_fastrtps_c'] / pkg)
    GeneratePython('py', typesupport_implementations=['rosidl_typesupport_c'] + TYPESUPPORTS
                   ).generate(pkg, idl, include, build / 'py' / pkg)
    return idl, json_files


def compile_flags(venv, build):
    """Include dirs: every package under .venv/include, generated headers, Python, numpy."""
    import numpy
    incs = [build / d for d in (*GEN_DIRS.values(), 'py')]
    incs += [venv / 'include'] + sorted(p for p in (venv / 'include').iterdir() if p.is_dir())
    incs += [pathlib.Path(sysconfig.get_paths()['include']), pathlib.Path(numpy.get_include())]
    return ['-O1', '-fPIC', '-shared', '-w'] + [f'-I{p}' for p in incs]


def build_libs(pkg, venv, build, flags):
    """Compile the C libraries of pkg into .venv/lib (generator_c first, then typesupports)."""
    lib = venv / 'lib'
    deps = PACKAGES[pkg]

    def so(part, ext, cc, runtime):
        srcs = sorted((build / GEN_DIRS[part] / pkg).rglob(f'*.{ext}'))
        own = [] if part == 'rosidl_generator_c' else [f'-l{pkg}__rosidl_generator_c']
        libs = own + [f'-l{d}__{p}' for p in {part, 'rosidl_generator_c'} for d in deps]
        run([cc, *flags, *map(str, srcs), '-o', str(lib / f'lib{pkg}__{part}.so'),
             '-Wl,--no-undefined', f'-L{lib}', *libs, *[f'-l{x}' for x in runtime]])

    so('rosidl_generator_c', 'c', 'gcc', ['rosidl_runtime_c', 'rcutils'])
    jobs = [
        ('rosidl_typesupport_introspection_c', 'c', 'gcc',
         ['rosidl_typesupport_introspection_c', 'rosidl_runtime_c', 'rcutils']),
        ('rosidl_typesupport_fastrtps_c', 'cpp', 'g++',
         ['rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_fastrtps_cpp', 'fastcdr', 'rmw',
          'rosidl_dynamic_typesupport', 'rosidl_runtime_c', 'rcutils']),
        ('rosidl_typesupport_c', 'cpp', 'g++',
         ['rosidl_typesupport_c', 'rosidl_runtime_c', 'rcpputils', 'rcutils']),
    ]
    with cf.ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
        for f in [pool.submit(so, *job) for job in jobs]:
            f.result()


def build_python(pkg, venv, build, flags):
    """Stage the generated Python package (build/site/<pkg>) with its C support + extension
    modules compiled; return the staged folder."""
    lib = venv / 'lib'
    src = build / 'py' / pkg
    dest = build / 'site' / pkg
    shutil.rmtree(dest, ignore_errors=True)
    shutil.copytree(src, dest, ignore=shutil.ignore_patterns('*.c', 'tmp'))
    (dest / '__init__.py').touch()
    deps = PACKAGES[pkg]
    common = [f'-L{lib}', f'-l{pkg}__rosidl_generator_c', f'-l{pkg}__rosidl_typesupport_c',
              *[f'-l{d}__rosidl_generator_py' for d in deps],
              *[f'-l{d}__rosidl_generator_c' for d in deps],
              *[f'-l{d}__rosidl_typesupport_c' for d in deps],
              '-lrosidl_runtime_c', '-lrcutils']
    run(['gcc', *flags, *map(str, sorted(src.rglob('_*_s.c'))),
         '-o', str(lib / f'lib{pkg}__rosidl_generator_py.so'), *common])

    def ext(ts):
        run(['gcc', *flags, str(src / f'_{pkg}_s.ep.{ts}.c'),
             '-o', str(dest / f'{pkg}_s__{ts}.so'),
             f'-l{pkg}__rosidl_generator_py', f'-l{pkg}__{ts}', *common, '-lrmw'])
    with cf.ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
        for f in [pool.submit(ext, ts) for ts in ['rosidl_typesupport_c'] + TYPESUPPORTS]:
            f.result()
    return dest


def install_share(pkg, venv, idl, json_files):
    """Copy definitions, .idl and .json to .venv/share/<pkg>; register pkg in the ament index."""
    share = venv / 'share' / pkg
    shutil.rmtree(share, ignore_errors=True)
    root, rel_files = interface_files(pkg)
    names = []
    for rel in rel_files:
        (share / rel.parent).mkdir(parents=True, exist_ok=True)
        shutil.copy2(root / rel, share / rel)
        names.append(str(rel))
    for tup in idl + [str(j) for j in json_files]:
        prefix, _, rel = tup.rpartition(':') if ':' in tup else ('', '', tup)
        src = pathlib.Path(prefix) / rel if prefix else pathlib.Path(rel)
        target = share / src.parent.name / src.name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, target)
        names.append(f'{src.parent.name}/{src.name}')
    shutil.copy2(root / 'LICENSE', share / 'LICENSE')
    index = venv / 'share' / 'ament_index' / 'resource_index'
    for kind, text in (('packages', ''), ('rosidl_interfaces', '\n'.join(sorted(names)))):
        (index / kind).mkdir(parents=True, exist_ok=True)
        (index / kind / pkg).write_text(text)


def build_package(pkg, venv, build):
    """Generate, compile and install one package; return its number of interfaces."""
    site = venv / 'lib' / f'python{sys.version_info[0]}.{sys.version_info[1]}' / 'site-packages'
    idl, json_files = generate(pkg, venv / 'share', build)
    flags = compile_flags(venv, build)
    build_libs(pkg, venv, build, flags)
    staged = build_python(pkg, venv, build, flags)
    install_share(pkg, venv, idl, json_files)
    # last, in one rename: a process importing pkg meanwhile (make demo runs beside this
    # build) finds either no package or the whole one, with its libraries in place
    shutil.rmtree(site / pkg, ignore_errors=True)
    os.replace(staged, site / pkg)
    return len(idl)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--venv', default=os.environ.get('VIRTUAL_ENV', str(HERE.parent / '.venv')))
    args = ap.parse_args(argv)
    venv = pathlib.Path(args.venv).resolve()
    build = venv / 'build-interfaces'
    shutil.rmtree(build, ignore_errors=True)
    for tool in ('gcc', 'g++'):
        if shutil.which(tool) is None:
            sys.exit(f'[gen_interfaces] error: {tool} not found (apt-get install gcc g++)')
    if not (pathlib.Path(sysconfig.get_paths()['include']) / 'Python.h').exists():
        sys.exit('[gen_interfaces] error: Python.h not found (Debian: apt-get install '
                 'python3.11-dev)')
    # the generators' templates and the dependencies' .idl/.json: the venv's, not a sourced
    # ROS install's (get_package_share_directory)
    os.environ['AMENT_PREFIX_PATH'] = str(venv)
    t0 = time.monotonic()
    # one process per package (the generators are single-threaded Python)
    with cf.ProcessPoolExecutor(max_workers=len(PACKAGES)) as pool:
        jobs = {pkg: pool.submit(build_package, pkg, venv, build) for pkg in PACKAGES}
        for pkg, job in jobs.items():
            log(f'{pkg}: {job.result()} interfaces built')
    log(f'done in {time.monotonic() - t0:.1f} s')


if __name__ == '__main__':
    main()

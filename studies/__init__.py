"""One-off analyses of the real arms (issue 22), kept beside the package (issue 43).

Each study runs from the repository root as ``python -m studies.<name> [options]`` with
the package's exit codes; studies/README.md lists them. The flex-twin packages never
import this package.
"""

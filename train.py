"""``python train.py <command>``: the same command line as ``attitude-envs`` (see :mod:`experiments.cli`)."""

from experiments.cli import main

if __name__ == "__main__":
    raise SystemExit(main())

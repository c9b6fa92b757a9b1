"""``python -m dualpixel`` (and ``torchrun -m dualpixel train ...`` for multi-GPU training)."""

from dualpixel.cli.main import run

if __name__ == "__main__":
    run()

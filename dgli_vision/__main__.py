"""``python -m dgli_vision``: the ``dgli`` command."""

from dgli_vision.cli import main

if __name__ == "__main__":
    main()

"""``python -m sensorispace_ros.cli``: the ``sensorispace`` command."""
import sys

from sensorispace_ros.cli.main import main

sys.exit(main())

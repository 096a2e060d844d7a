import sys

from jointbench.benchmarks.cli import main

sys.exit(main())

"""Shared test set-up: keep DDS on this machine, in a domain of this test run's own."""
from __future__ import annotations

import os
import random
import sys
from pathlib import Path

# The helpers every test folder shares (harnesses, stand-ins, laws run by name in other
# processes) live in test/support/ and import by their module name.
sys.path.insert(0, str(Path(__file__).resolve().parent / 'support'))

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 100)))
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
# Fast DDS sockets on 127.0.0.1 only, for the node, the probes and every other process.
LOOPBACK_PROFILE = str(Path(__file__).resolve().parents[1] / 'config' / 'fastdds_localhost.xml')
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', LOOPBACK_PROFILE)
os.environ.setdefault('FASTDDS_DEFAULT_PROFILES_FILE', LOOPBACK_PROFILE)

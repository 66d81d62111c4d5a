"""The core modules import without ROS and without flex_planner (ARCHITECTURE.md)."""
import subprocess
import sys
from pathlib import Path

import flex_control

PKG = Path(flex_control.__file__).resolve().parent
ROS_MODULES = {"controller_node", "ros_conversions"}
CORE = sorted(p.stem for p in PKG.glob("*.py")
              if p.stem not in ROS_MODULES and p.stem != "__init__")

PROBE = """
import importlib, sys
class Block:
    def find_spec(self, name, path=None, target=None):
        root = name.split('.')[0]
        if root in {'rclpy', 'rcl_interfaces', 'sensor_msgs', 'std_msgs', 'trajectory_msgs',
                    'flex_planner'}:
            raise ImportError('blocked: ' + name)
sys.meta_path.insert(0, Block())
for m in sys.argv[1:]:
    importlib.import_module('flex_control.' + m)
bad = [m for m in sys.modules if m.split('.')[0] in ('rclpy', 'flex_planner')]
print('loaded', bad)
sys.exit(1 if bad else 0)
"""


def test_core_modules_import_without_ros_or_planner():
    assert {"laws", "closed_loop", "design", "gain_schedule", "ltv", "cli"} <= set(CORE)
    proc = subprocess.run([sys.executable, "-c", PROBE, *CORE], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_node_module_needs_ros():
    proc = subprocess.run([sys.executable, "-c", PROBE, "controller_node"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0 and ("blocked: rclpy" in proc.stderr
                                     or "blocked: rcl_interfaces" in proc.stderr)

"""Write tests/data/realsense_sdk2.56.bag: a small RealSense recording in the ROS 1 layout
of the RealSense SDK before 2.58 (the RealSense Viewer's .bag), which SDK 2.59 can read
but no longer write. Run it with pyrealsense2 2.56 on the path, e.g.

    pip install --target /tmp/rs256 'pyrealsense2==2.56.5.9235'
    PYTHONPATH=/tmp/rs256:. .venv/bin/python scripts/realsense_fixture.py

The frames are tests/test_realsense.py's pattern_frames(): the test writes the same
frames with the installed SDK as a .db3 and checks that both read back alike.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_realsense import PATTERN_INTRINSICS, pattern_frames

from dgli_vision.sources.realsense_writer import write_realsense_recording

if __name__ == "__main__":
    out = Path(__file__).resolve().parents[1] / "tests" / "data" / "realsense_sdk2.56.bag"
    out.unlink(missing_ok=True)
    write_realsense_recording(out, pattern_frames(), PATTERN_INTRINSICS)
    print(f"wrote {out} ({out.stat().st_size} bytes)")

"""Record tests/data/ros2bag/sim_office.mcap: `missiontree sim-ros` (office, unknown map) over DDS.

The robot is sent to a goal while ``missiontree.backends.ros2.bag_record.record_bag`` records the
TurtleBot 4 topics (camera thinned to 1 frame a second), so the bag holds motion, a growing /map
and a few RGB-D frames. Needs the ros2 extra; run from the repository root:

    python tests/data/ros2bag/record_sim_bag.py [OUT] [SECONDS]
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
DOMAIN = 97
CAMERA = ("/oakd/rgb/preview/image_raw", "/oakd/rgb/preview/camera_info", "/oakd/stereo/image_raw")


def main() -> int:
    """Start sim-ros, drive to a goal while recording, stop sim-ros; print the summary."""
    from missiontree.backends.ros2.bag_record import record_bag
    from missiontree.backends.ros2.profile import load_profile
    from missiontree.backends.ros2.robot import Ros2Robot
    from missiontree.types import Pose2D, Tolerance

    out = Path(sys.argv[1] if len(sys.argv) > 1 else "tests/data/ros2bag/sim_office.mcap")
    seconds = float(sys.argv[2]) if len(sys.argv) > 2 else 12.0
    env = dict(os.environ, ROS_DOMAIN_ID=str(DOMAIN))
    server = subprocess.Popen([sys.executable, "-m", "missiontree.cli.main", "sim-ros", "--world", "office",
                               "--unknown-map"], env=env)
    try:
        robot = Ros2Robot(load_profile("turtlebot4", {"domain_id": DOMAIN}), node_name="bag_driver",
                          install_signal_stop=False)
        deadline = time.monotonic() + 30
        while not (robot.pose() and robot.scan()) and time.monotonic() < deadline:
            time.sleep(0.1)
        result: dict = {}
        recorder = threading.Thread(target=lambda: result.update(summary=record_bag(
            out, seconds, domain_id=DOMAIN, max_rate={t: 1.0 for t in CAMERA})))
        recorder.start()
        time.sleep(1.0)  # the recorder has discovered the topics
        robot.navigate_to(Pose2D(7.5, 3.6, 0.0), Tolerance(xy=0.25, yaw=2 * math.pi))
        recorder.join()
        robot.close()
        print(result["summary"])
        return 0
    finally:
        server.terminate()
        server.wait(timeout=10)


if __name__ == "__main__":
    raise SystemExit(main())

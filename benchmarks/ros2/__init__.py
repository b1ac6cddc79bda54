"""ROS 2 bags in MCAP: the message definitions the project reads and writes (`msgs`), the topics it uses
(`topics`) and writing an episode as a bag (`writer`, for `msvdd-bench export-bag`); reading bags is the
ros2 layout of `msvdd-bench import` (`benchmarks.importers.bags`, `benchmarks.importers.ros2`). Encoding and
decoding are `mcap` and `mcap-ros2-support`'s; no ROS installation is needed.
"""

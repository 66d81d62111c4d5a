"""The twin diagnosis workflow (issue 8): replay a measured run through the nominal twin in
closed loop, recalibrate within tolerance, gate, localise, name the missing effect, write
the updated arm. ROS-free; ``cli.py`` is the ``flex-twin diagnose`` subcommand."""

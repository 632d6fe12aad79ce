"""What the commands, scripts and labs share: plant profiles, scenarios, the evaluation loop, the trainers, the
yardstick, the command-line options several commands take. It imports the library and itself, never a command, a
script or a lab."""

"""ROS 2 adapter serving 900-step hybrid ship-motion forecasts and a what-if service."""

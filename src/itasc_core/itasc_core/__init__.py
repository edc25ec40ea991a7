"""Composition Pattern runtime of iTaSC-ROS2 (entities, events, life-cycle FSM, composer, configurator, scheduler,
monitors, ports) and the constraint-based program entities (Robot, Object, Scene, Solver)."""

"""The robots shipped with snake_pin, as package data.

``snake_pin.robots.urdf`` holds the generated URDFs of the presets (the repository's
``urdf/``) and ``snake_pin.robots.examples`` the example robot files (the repository's
``examples/robots/``); :func:`snake_pin.robot_file.robot_paths` returns their paths.
"""

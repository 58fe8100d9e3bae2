"""The robots shipped with snake_pin, as package data: ``snake_pin.robots.urdf`` the presets'
URDFs (the repository's ``urdf/``), ``snake_pin.robots.examples`` the example robot files
(``examples/robots/``); :func:`snake_pin.robot_file.robot_paths` returns their paths.
"""

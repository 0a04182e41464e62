"""The vehicle and its sky: rigid body, quaternions, Sun and stars.

``plant`` integrates Euler's equations and the quaternion kinematics in the
compiled frame loop; ``plant_control`` states the same equations as a
python-control nonlinear system for analysis; ``sky`` gives the Sun and
catalog stars for the mission date.
"""

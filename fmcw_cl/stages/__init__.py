"""The method's stages as plain numpy functions on arrays: the reference backend.

lpf -> sync -> lut -> resample -> spectrum -> pairing -> kinematics
"""

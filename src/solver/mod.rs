//! Vector radiative transfer by discrete ordinates (stub).

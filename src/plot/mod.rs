//! Plots of BRDF results (`polbrdf plot ...`): the seed's figures as SVG/PNG
//! with the plotted numbers next to them as CSV (issue 7).

//! A small CPU polarized preview renderer (`polbrdf render ...`): spheres with
//! BRDF tables on a depolarizing floor, Mueller calculus per path (issue 7).

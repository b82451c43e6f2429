// Placeholder until kernel.cc lands: the skeleton links.
#include "kernel.h"
namespace mjrft::kernel {
Medium MediumOf(const Tables& t) {
  return {t.coef, t.ncoef, t.alpha_y, t.zeta, t.surface_prm, t.surface_grid, t.use_region != 0,
          t.region};
}
Elements ElementsOf(const Tables& t) {
  return {t.elem_pos, t.elem_normal, t.elem_area, t.elem_reach, t.elem_patch};
}
int BodyWrench(const Elements&, i64, i64, const Medium&, const f64*, const f64*, const f64*,
               const f64*, const f64*, const f64*, const f64*, f64*, f64*, f64*) {
  return 0;
}
}  // namespace mjrft::kernel

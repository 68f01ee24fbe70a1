// A program outside the aerotri tree that uses the installed package:
// solves a BAL problem with the bundle adjuster and prints the RMS.
#include <iostream>

#include "libphoto/adjust/bundle_adjuster.h"
#include "libphoto/io/bal.h"

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  aerotri::SparseModel model = aerotri::ReadBalProblem(argv[1]);
  const aerotri::BundleSummary summary = aerotri::AdjustBundle(&model, aerotri::BundleOptions());
  std::cout << "cameras=" << model.images.size() << " rms_px=" << summary.final_rms_px << "\n";
  return summary.termination.rfind("FAILURE", 0) == 0 ? 1 : 0;
}

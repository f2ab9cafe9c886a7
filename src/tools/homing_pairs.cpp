// homing_pairs: the horizontal shift between image pairs with a known true shift, measured by the
// package's homing estimator (HomingEstimator), by the matching's strip search (ImageDifference) and by
// OpenCV phase correlation, all on the images preprocessed as the package does. scripts/evaluate_homing
// runs it and computes the figures.
//   homing_pairs --pairs pairs.csv [--true-width 1024] [--homing M:V:S[:FIT[:robust]] ...] [--set name=value ...]
//                [--save-preprocessed DIR]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "along_route_localization/homing.h"
#include "along_route_localization/image_difference.h"
#include "along_route_localization/localizer.h"
#include "along_route_localization/parameters.h"
#include "along_route_localization/preprocessing.h"

namespace alr = along_route_localization;

namespace
{

void usage(std::ostream& out)
{
  out << "usage: homing_pairs --pairs pairs.csv [--true-width PX] [--homing M:V:S[:FIT[:robust]] ...]\n"
         "                    [--set name=value ...]\n"
         "                    [--save-preprocessed DIR]\n"
         "  pairs.csv: header place,map_image,query_image,true_shift_px (image paths absolute or relative to\n"
         "        the CSV's folder; true_shift_px: the query's content lies this far to the RIGHT of the map image's,\n"
         "        in px of an image --true-width px wide, default 1024). Every image is preprocessed with\n"
         "        the package's parameters (defaults; --set name=value overrides, e.g. sky_fraction=0.25).\n"
         "  --homing M:V:S[:FIT[:robust]]: measure with HomingEstimator(max_shift_px M, max_vertical_shift_px V,\n"
         "        kept_column_share S, subpixel fit parabola or equiangular, default equiangular; robust:\n"
         "        robust_column_cost); one column per option, named homing_M_V_S_FIT[_robust]. Without any: the Localizer's homing_max_shift_px and\n"
         "        homing_max_vertical_shift_px (defaults, or given with --set), the rest at its defaults.\n"
         "  Output CSV on stdout: place,map_image,query_image,true_shift_px (in px of the preprocessed\n"
         "        width), strip_sad (the matching's search, max_shift_px), phase_correlation (on the\n"
         "        preprocessed images, Hanning window), phase_correlation_gray (on the grayscale images\n"
         "        resized to the same size, Hanning window), then the homing columns.\n"
         "  --save-preprocessed DIR: also write every preprocessed image into DIR (an existing folder),\n"
         "        named by its path with '/' replaced by '_'.\n";
}

struct Pair
{
  std::string place, map_image, query_image;
  double true_shift_px = 0.0;
};

bool readPairs(const std::string& path, std::vector<Pair>* pairs, std::string* error)
{
  std::ifstream in(path);
  if (!in)
  {
    *error = "cannot read " + path;
    return false;
  }
  std::string line;
  std::getline(in, line);
  if (line.rfind("place,map_image,query_image,true_shift_px", 0) != 0)
  {
    *error = path + ": the header must be place,map_image,query_image,true_shift_px";
    return false;
  }
  int number = 1;
  while (std::getline(in, line))
  {
    ++number;
    if (!line.empty() && line.back() == '\r')
      line.pop_back();
    if (line.empty())
      continue;
    std::stringstream fields(line);
    Pair pair;
    std::string shift;
    if (!std::getline(fields, pair.place, ',') || !std::getline(fields, pair.map_image, ',') ||
        !std::getline(fields, pair.query_image, ',') || !std::getline(fields, shift, ','))
    {
      *error = path + ":" + std::to_string(number) + ": expected 4 fields";
      return false;
    }
    try
    {
      size_t used = 0;
      pair.true_shift_px = std::stod(shift, &used);
      if (used != shift.size() || !std::isfinite(pair.true_shift_px))
        throw std::invalid_argument(shift);
    }
    catch (const std::exception&)
    {
      *error = path + ":" + std::to_string(number) + ": true_shift_px '" + shift + "' is not a number";
      return false;
    }
    pairs->push_back(pair);
  }
  return true;
}

/// An image preprocessed as the package does, and the same image only grayscaled and resized.
struct Images
{
  cv::Mat preprocessed, gray;
};

double phaseCorrelationShift(const cv::Mat& keyframe, const cv::Mat& query, const cv::Mat& window)
{
  cv::Mat k, q;
  keyframe.convertTo(k, CV_64F);
  query.convertTo(q, CV_64F);
  // phaseCorrelate(a, b) answers +d for b = a with its content moved d px to the right.
  return cv::phaseCorrelate(k, q, window).x;
}

/// The whole of `text` as a finite number (parseDouble takes "nan" and "inf" too).
bool finiteNumber(const std::string& text, double* value)
{
  return alr::parseDouble(text, value) && std::isfinite(*value);
}

}  // namespace

int main(int argc, char** argv)
{
  std::string pairs_path, save_folder;
  double true_width = 1024.0;
  std::vector<alr::HomingParams> homing_options;
  alr::PreprocessingParams preprocessing;
  alr::LocalizerParams localizer;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "-h" || arg == "--help")
    {
      usage(std::cout);
      return 0;
    }
    else if (arg == "--pairs" && has_value)
      pairs_path = argv[++i];
    else if (arg == "--save-preprocessed" && has_value)
      save_folder = argv[++i];
    else if (arg == "--true-width" && has_value)
    {
      const std::string text = argv[++i];
      if (!finiteNumber(text, &true_width) || !(true_width > 0.0))
      {
        std::cerr << "homing_pairs: --true-width takes the width in px of the images the true shifts are measured "
                     "on (> 0), got '"
                  << text << "'\n";
        return 2;
      }
    }
    else if (arg == "--homing" && has_value)
    {
      const std::string spec = argv[++i];
      alr::HomingParams params;
      std::stringstream fields(spec);
      std::string shift, vertical, share, fit, robust, rest;
      std::getline(fields, shift, ':');
      std::getline(fields, vertical, ':');
      std::getline(fields, share, ':');
      std::getline(fields, fit, ':');
      std::getline(fields, robust, ':');
      std::getline(fields, rest);
      if (!alr::parseInt(shift, &params.max_shift_px) || !alr::parseInt(vertical, &params.max_vertical_shift_px) ||
          !finiteNumber(share, &params.kept_column_share) ||
          (!fit.empty() && fit != "parabola" && fit != "equiangular") || (!robust.empty() && robust != "robust") ||
          !rest.empty())
      {
        std::cerr << "homing_pairs: --homing takes M:V:S[:parabola|equiangular[:robust]] (M and V integers, S a "
                     "number), got "
                  << spec << "\n";
        return 2;
      }
      if (!fit.empty())
        params.subpixel_fit = fit == "parabola" ? alr::SubpixelFit::kParabola : alr::SubpixelFit::kEquiangular;
      params.robust_column_cost = robust == "robust";
      homing_options.push_back(params);
    }
    else if (arg == "--set" && has_value)
    {
      const std::string assignment = argv[++i];
      const size_t eq = assignment.find('=');
      std::string error;
      if (eq == std::string::npos ||
          !alr::applyParameter(assignment.substr(0, eq), assignment.substr(eq + 1), &preprocessing, &localizer, &error))
      {
        std::cerr << "homing_pairs: --set " << assignment << ": " << (error.empty() ? "expected name=value" : error)
                  << "\n";
        return 2;
      }
    }
    else
    {
      std::cerr << "homing_pairs: unknown or incomplete argument " << arg << "\n";
      usage(std::cerr);
      return 2;
    }
  }
  if (pairs_path.empty())
  {
    std::cerr << "homing_pairs: --pairs is required\n";
    usage(std::cerr);
    return 2;
  }
  std::string error = preprocessing.validate();
  if (error.empty())
    error = localizer.validate();
  if (!error.empty())
  {
    std::cerr << "homing_pairs: " << error << "\n";
    return 2;
  }
  if (homing_options.empty())
  {
    alr::HomingParams params;
    params.max_shift_px = localizer.homing_max_shift_px;
    params.max_vertical_shift_px = localizer.homing_max_vertical_shift_px;
    homing_options.push_back(params);
  }

  std::vector<Pair> pairs;
  if (!readPairs(pairs_path, &pairs, &error))
  {
    std::cerr << "homing_pairs: " << error << "\n";
    return 1;
  }
  const size_t slash = pairs_path.find_last_of('/');
  const std::string folder = slash == std::string::npos ? "." : pairs_path.substr(0, slash);

  const int width = preprocessing.output_width, height = preprocessing.output_height;
  const int first_row = preprocessing.skyRows();
  alr::Preprocessor preprocessor(preprocessing);
  std::map<std::string, Images> images;
  for (const Pair& pair : pairs)
    for (const std::string& name : { pair.map_image, pair.query_image })
    {
      if (images.count(name))
        continue;
      const std::string path = !name.empty() && name[0] == '/' ? name : folder + "/" + name;
      const cv::Mat bgr = cv::imread(path, cv::IMREAD_COLOR);
      if (bgr.empty())
      {
        std::cerr << "homing_pairs: cannot read the image " << path << "\n";
        return 1;
      }
      Images& out = images[name];
      preprocessor.process(bgr, alr::PixelFormat::kBgr8, out.preprocessed);
      cv::Mat gray;
      cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
      cv::resize(gray, out.gray, cv::Size(width, height), 0.0, 0.0, cv::INTER_AREA);
      if (!save_folder.empty())
      {
        std::string flat = name;
        std::replace(flat.begin(), flat.end(), '/', '_');
        if (!cv::imwrite(save_folder + "/" + flat, out.preprocessed))
        {
          std::cerr << "homing_pairs: cannot write " << save_folder << "/" << flat << "\n";
          return 1;
        }
      }
    }

  alr::ImageDifference strip(width, height, first_row, localizer.max_shift_px, localizer.subpixel_shift);
  std::vector<std::unique_ptr<alr::HomingEstimator>> estimators;
  try
  {
    for (const alr::HomingParams& params : homing_options)
      estimators.emplace_back(new alr::HomingEstimator(width, height, first_row, params));
  }
  catch (const std::invalid_argument& e)
  {
    std::cerr << "homing_pairs: " << e.what() << "\n";
    return 2;
  }
  cv::Mat window;
  cv::createHanningWindow(window, cv::Size(width, height), CV_64F);

  std::printf("place,map_image,query_image,true_shift_px,strip_sad,phase_correlation,phase_correlation_gray");
  for (const alr::HomingParams& params : homing_options)
    std::printf(",homing_%d_%d_%g_%s%s", params.max_shift_px, params.max_vertical_shift_px, params.kept_column_share,
                params.subpixel_fit == alr::SubpixelFit::kParabola ? "parabola" : "equiangular",
                params.robust_column_cost ? "_robust" : "");
  std::printf("\n");
  for (const Pair& pair : pairs)
  {
    const Images& map = images[pair.map_image];
    const Images& query = images[pair.query_image];
    std::printf("%s,%s,%s,%.4f,%.4f,%.4f,%.4f", pair.place.c_str(), pair.map_image.c_str(), pair.query_image.c_str(),
                pair.true_shift_px * width / true_width, strip.compare(query.preprocessed.data, map.preprocessed.data).shift_px,
                phaseCorrelationShift(map.preprocessed, query.preprocessed, window),
                phaseCorrelationShift(map.gray, query.gray, window));
    for (auto& estimator : estimators)
      std::printf(",%.4f", estimator->estimate(query.preprocessed.data, map.preprocessed.data).shift_px);
    std::printf("\n");
  }
  return 0;
}

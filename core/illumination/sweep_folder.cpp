#include "nirslam/illumination/sweep_folder.hpp"

#include <fstream>
#include <string_view>

#include <nlohmann/json.hpp>

#include "nirslam/common/error.hpp"
#include "nirslam/common/text_fields.hpp"
#include "nirslam/image/image_files.hpp"

namespace nirslam {
namespace fs = std::filesystem;

namespace {

std::optional<std::string> scene_of_ground_truth(const fs::path& file) {
  std::error_code error;
  if (!fs::is_regular_file(file, error)) return std::nullopt;
  std::ifstream in(file);
  const nlohmann::json json = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (json.is_discarded()) throw InputError(file, "not valid JSON");
  const auto scene = json.find("scene");
  if (scene == json.end() || !scene->is_object()) return std::nullopt;
  const auto kind = scene->find("kind");
  if (kind == scene->end() || !kind->is_string()) return std::nullopt;
  return kind->get<std::string>();
}

}  // namespace

SweepFolder read_sweep_folder(const fs::path& folder) {
  SweepFolder sweep;
  sweep.folder = folder;
  sweep.table = folder / "sweep.csv";
  std::error_code error;
  if (!fs::is_directory(folder, error)) throw InputError(folder, "not a folder");
  std::ifstream in(sweep.table);
  if (!in) throw InputError(sweep.table, "cannot open: a sweep folder holds sweep.csv (file,power_w[,scene])");

  std::optional<std::size_t> file_column, power_column, scene_column;
  std::size_t columns = 0;
  std::string text;
  int line = 0;
  while (std::getline(in, text)) {
    ++line;
    const std::string_view row = trim(text);
    if (row.empty() || row.front() == '#') continue;
    const std::vector<std::string_view> fields = split_fields(row);
    if (columns == 0) {
      columns = fields.size();
      for (std::size_t i = 0; i < fields.size(); ++i) {
        const std::string name = lowercase(fields[i]);
        if (name == "file") file_column = i;
        else if (name == "power_w") power_column = i;
        else if (name == "scene") scene_column = i;
      }
      if (!file_column || !power_column)
        throw InputError(sweep.table, line, "the header must name the columns 'file' and 'power_w' (and optionally "
                                            "'scene'), got '" + std::string(row) + "'");
      continue;
    }
    if (fields.size() != columns)
      throw InputError(sweep.table, line, "expected " + std::to_string(columns) + " fields as in the header, got " +
                                              std::to_string(fields.size()));
    SweepImage image;
    image.line = line;
    const std::string_view name = fields[*file_column];
    if (name.empty()) throw InputError(sweep.table, line, "field 'file' is empty");
    image.file = fs::path(name).is_absolute() ? fs::path(name) : folder / fs::path(name);
    const auto power = parse_double(fields[*power_column]);
    if (!power || *power < 0.0)
      throw InputError(sweep.table, line, "field 'power_w': expected watts >= 0, got '" +
                                              std::string(fields[*power_column]) + "'");
    image.power_w = *power;
    if (scene_column) image.scene = std::string(fields[*scene_column]);
    if (!fs::is_regular_file(image.file, error))
      throw InputError(sweep.table, line, "image '" + std::string(name) + "' not found (" + image.file.string() + ")");
    sweep.images.push_back(std::move(image));
  }
  if (in.bad()) throw InputError(sweep.table, "cannot read");
  if (columns == 0) throw InputError(sweep.table, "empty: expected a header 'file,power_w' and one line per image");
  if (sweep.images.empty()) throw InputError(sweep.table, "lists no images");
  sweep.ground_truth_scene = scene_of_ground_truth(folder / "groundtruth.json");
  return sweep;
}

std::map<std::string, SweepRecord> measure_sweep(const SweepFolder& folder, QualityMeter& meter,
                                                 const std::string& default_scene) {
  std::map<std::string, SweepRecord> records;
  for (const SweepImage& image : folder.images) {
    GreyImageDecoder::Image grey;
    try {
      grey = read_grey_image(image.file);
    } catch (const InputError& e) {
      throw InputError(folder.table, image.line, e.what());
    }
    const std::string& scene = image.scene.empty() ? default_scene : image.scene;
    auto it = records.find(scene);
    if (it == records.end()) it = records.emplace(scene, SweepRecord(scene)).first;
    it->second.add(image.power_w, meter.measure(grey.image, grey.bit_depth));
  }
  return records;
}

}  // namespace nirslam

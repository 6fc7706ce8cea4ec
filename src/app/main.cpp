// typemerge: CT series in, printable surfaces out. Commands are composed here and only here.
#include <CLI/CLI.hpp>

#include <iostream>
#include <system_error>

#include "app/batch_command.h"
#include "app/convert_command.h"
#include "app/exit_codes.h"
#include "app/info_command.h"
#include "app/presets_command.h"
#include "app/stats_command.h"
#include "app/volume_command.h"
#include "app/version.h"

int main(int argc, char** argv) {
  using namespace typemerge::app;
  CLI::App app{"typemerge: from a CT DICOM folder to a printable surface"};
  app.set_version_flag("--version", std::string(kVersion));
  app.require_subcommand(1);
  InfoOptions info;
  VolumeOptions volume;
  ConvertOptions convert;
  StatsOptions stats;
  BatchOptions batch;
  add_info_command(app, info);
  add_volume_command(app, volume);
  add_convert_command(app, convert);
  add_batch_command(app, batch);
  add_stats_command(app, stats);
  add_presets_command(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& help) {
    return app.exit(help);
  } catch (const CLI::CallForVersion& version) {
    return app.exit(version);
  } catch (const CLI::ParseError& error) {
    app.exit(error);
    return kExitUsage;
  }

  try {
    if (app.got_subcommand("info")) return run_info(info, std::cout);
    if (app.got_subcommand("volume")) return run_volume(volume, std::cerr);
    if (app.got_subcommand("convert")) return run_convert(convert, std::cerr);
    if (app.got_subcommand("batch")) return run_batch(batch, std::cerr);
    if (app.got_subcommand("stats")) return run_stats(stats, std::cout);
    if (app.got_subcommand("presets")) return run_presets(std::cout);
  } catch (const CommandError& error) {
    std::cerr << "typemerge: " << error.message << "\n";
    return error.exit_code;
  } catch (const std::bad_alloc&) {
    std::cerr << "typemerge: out of memory\n";
    return kExitInputRefused;
  } catch (const std::system_error& error) {
    // A thread that cannot be created under a memory limit is the same condition.
    if (error.code() == std::errc::resource_unavailable_try_again ||
        error.code() == std::errc::not_enough_memory) {
      std::cerr << "typemerge: out of memory\n";
      return kExitInputRefused;
    }
    std::cerr << "typemerge: internal error: " << error.what() << "\n";
    return kExitInternal;
  } catch (const std::exception& error) {
    std::cerr << "typemerge: internal error: " << error.what() << "\n";
    return kExitInternal;
  }
  return kExitUsage;
}

// The command table. Add a command here and in command.h; nothing registers itself.
#include "rig/commands/command.h"

namespace rig {

int RunExport(int argc, char** argv);  // rig/commands/export.cc
int RunCollection(int argc, char** argv);  // rig/commands/collection.cc

const std::vector<Command>& Commands() {
  static const std::vector<Command> kCommands = {
      {"capture", "acquire a session (on the rig, or simulated with --dry-run)", RunCapture},
      {"resume", "continue an interrupted session", RunResume},
      {"process", "(re)process stored brackets into radiance maps and the model", RunProcess},
      {"check-config", "validate a configuration file", RunCheckConfig},
      {"hdr", "merge one exposure bracket into a radiance map (EXR)", RunHdr},
      {"ratio-check", "the paper's Fig. 6: pixel ratios from intensity vs radiance", RunRatioCheck},
      {"fit", "fit a reflectance model to radiance maps or an RTI capture", RunFit},
      {"render", "relight a reflectance model with lamps", RunRender},
      {"evaluate", "speed against accuracy of every method: tables, charts, stability report", RunEvaluate},
      {"export", "write a model in relight's web format, or as a .ptm or .rti file", RunExport},
      {"tonemap", "tone-map an HDR image (.exr, .hdr) for a screen", RunTonemap},
      {"collection", "many sessions and .lp captures through a Snakemake workflow: init, report", RunCollection},
      {"view", "write a self-contained WebGL2 relighting page for a model", RunView},
      {"devices", "list cameras, serial ports and GPIO lines the rig could use", RunDevices},
      {"jog", "move the lamp arm to one pose (bring-up)", RunJog},
      {"home", "run the arm's homing cycle, or clear a GRBL alarm lock (bring-up)", RunHome},
      {"lamp", "switch the lamp on, off, or blink it (bring-up)", RunLamp},
      {"shot", "one frame at one exposure: histogram, clipping, a suggested bracket (bring-up)", RunShot},
      {"daemon", "the capture service: job queue, HTTP+JSON API, live status page", RunDaemon},
      {"status", "what a running 'rig daemon' is doing", RunStatus},
      {"calibrate-lights", "light directions from chrome spheres: an .lp, a session's [light_frame]", RunCalibrateLights},
      {"normals", "surface normals and albedo by photometric stereo (EXR + PNG)", RunNormals},
  };
  return kCommands;
}

}  // namespace rig

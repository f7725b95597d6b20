// The command table. Add a command here and in command.h; nothing registers itself.
#include "rig/commands/command.h"

namespace rig {

int RunExport(int argc, char** argv);  // rig/commands/export.cc
int RunCollection(int argc, char** argv);  // rig/commands/collection.cc

const char* CommandGroupTitle(CommandGroup group) {
  switch (group) {
    case CommandGroup::kAcquisition: return "Acquisition";
    case CommandGroup::kProcessing: return "Processing";
    case CommandGroup::kViewing: return "Viewing and export";
    case CommandGroup::kBringUp: return "Bring-up (one device at a time, on the real rig)";
    case CommandGroup::kService: return "Service";
  }
  return "";
}

const std::vector<Command>& Commands() {
  static const std::vector<Command> kCommands = {
      {CommandGroup::kAcquisition, "capture", "acquire a session (on the rig, or simulated with --dry-run)", RunCapture},
      {CommandGroup::kAcquisition, "resume", "continue an interrupted session", RunResume},
      {CommandGroup::kProcessing, "process", "(re)process stored brackets into radiance maps and the model", RunProcess},
      {CommandGroup::kAcquisition, "check-config", "validate a configuration file", RunCheckConfig},
      {CommandGroup::kProcessing, "hdr", "merge one exposure bracket into a radiance map (EXR)", RunHdr},
      {CommandGroup::kProcessing, "ratio-check", "the paper's Fig. 6: pixel ratios from intensity vs radiance", RunRatioCheck},
      {CommandGroup::kProcessing, "fit", "fit a reflectance model to radiance maps or an RTI capture", RunFit},
      {CommandGroup::kViewing, "render", "relight a reflectance model with lamps", RunRender},
      {CommandGroup::kProcessing, "evaluate", "speed against accuracy of every method: tables, charts, stability report", RunEvaluate},
      {CommandGroup::kViewing, "export", "a model in relight's web format or as .ptm/.rti; a session as an .lp capture", RunExport},
      {CommandGroup::kViewing, "tonemap", "tone-map an HDR image (.exr, .hdr) for a screen", RunTonemap},
      {CommandGroup::kProcessing, "collection", "many sessions and .lp captures through a Snakemake workflow: init, report", RunCollection},
      {CommandGroup::kViewing, "view", "write a self-contained WebGL2 relighting page for a model", RunView},
      {CommandGroup::kBringUp, "devices", "list cameras, serial ports and GPIO lines the rig could use", RunDevices},
      {CommandGroup::kBringUp, "jog", "move the lamp arm to one pose", RunJog},
      {CommandGroup::kBringUp, "home", "run the arm's homing cycle, or clear a GRBL alarm lock", RunHome},
      {CommandGroup::kBringUp, "lamp", "switch the lamp on, off, or blink it", RunLamp},
      {CommandGroup::kBringUp, "shot", "one frame at one exposure: histogram, clipping, a suggested bracket", RunShot},
      {CommandGroup::kService, "daemon", "the capture service: job queue, HTTP+JSON API, live status page", RunDaemon},
      {CommandGroup::kService, "status", "what a running 'rig daemon' is doing", RunStatus},
      {CommandGroup::kAcquisition, "calibrate-lights", "light directions from chrome spheres: an .lp, a session's [light_frame]", RunCalibrateLights},
      {CommandGroup::kProcessing, "lights", "choose the N lights a capture needs, one after another (next-best-light)", RunLights},
      {CommandGroup::kProcessing, "normals", "surface normals and albedo by photometric stereo (EXR + PNG)", RunNormals},
  };
  return kCommands;
}

}  // namespace rig

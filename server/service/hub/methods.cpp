#include "service/hub/methods.hpp"

#include <algorithm>
#include <array>

namespace marzipan::service {

using protocol::Method;

namespace {

constexpr std::array<MethodEntry, 25> kMethods{{
    {Method::SessionCreate, Access::Anyone, sessionCreate, true},
    {Method::SessionJoin, Access::Anyone, sessionJoin, true},
    {Method::SessionLeave, Access::Member, sessionLeave},
    {Method::SessionStats, Access::Member, sessionStats},
    {Method::ToolApply, Access::Editor, toolApply},
    {Method::StrokeBegin, Access::Editor, strokeBegin},
    {Method::StrokeDabs, Access::Editor, strokeDabs},
    {Method::StrokeEnd, Access::Editor, strokeEnd},
    {Method::VolumeMorph, Access::Editor, volumeMorph},
    {Method::HistoryUndo, Access::Editor, historyUndo},
    {Method::HistoryRedo, Access::Editor, historyRedo},
    {Method::ViewSet, Access::Member, viewSet},
    {Method::RenderFrame, Access::Member, renderFrame},
    {Method::SplatsGet, Access::Member, splatsGet},
    {Method::MeshExport, Access::Member, meshExport},
    {Method::VolumeSave, Access::Member, volumeSave},
    {Method::VolumeLoad, Access::Editor, volumeLoad, true},
    {Method::AnalysisThickness, Access::Member, analysisThickness},
    // Spelled so that Hub::text did not see it (escapes); see opCancel.
    {Method::OpCancel, Access::Anyone, opCancel},
    {Method::HistoryList, Access::Member, historyList},
    // A view client may fork: it sees the whole volume already, and the fork is its own.
    {Method::SessionFork, Access::Member, sessionFork},
    {Method::Presence, Access::Member, presence},
    {Method::MaskClear, Access::Editor, maskMethod},
    {Method::MaskInvert, Access::Editor, maskMethod},
    {Method::MaskFill, Access::Editor, maskMethod},
}};

}  // namespace

std::span<const MethodEntry> methodTable() { return kMethods; }

const MethodEntry* findMethod(Method m) {
  const auto it = std::find_if(kMethods.begin(), kMethods.end(), [m](const MethodEntry& e) { return e.method == m; });
  return it != kMethods.end() ? &*it : nullptr;
}

}  // namespace marzipan::service
